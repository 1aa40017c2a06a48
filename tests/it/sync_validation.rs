//! The validation layer checks synchronisation too: a missing barrier
//! between two commands is counted as a validation error (the test suite
//! asserts zero of them on every render).

use lancer::internal::vk::{Context, ContextOptions, MemoryKind, STAGING_CHUNK_BYTES};

/// A context under the Khronos validation layer. Fails the test when there
/// is no device or no layer.
fn validated() -> Context {
    Context::new(&ContextOptions {
        device: std::env::var("LANCER_DEVICE").ok(),
        validation: true,
    })
    .unwrap_or_else(|e| panic!("this test needs a Vulkan device and the validation layer: {e}"))
}

/// Fills a buffer and copies it, with or without a barrier in between, and
/// returns the validation errors counted.
fn fill_then_copy(barrier: bool) -> u32 {
    let ctx = validated();
    let a = ctx
        .create_buffer("test.a", 256, MemoryKind::Device)
        .unwrap();
    let b = ctx
        .create_buffer("test.b", 256, MemoryKind::Device)
        .unwrap();
    let mut rec = ctx.begin("hazard", 0).unwrap();
    rec.fill_buffer(&a, 0, 256, 7);
    if barrier {
        rec.barrier();
    }
    rec.copy_buffer(&a, 0, &b, 0, 256);
    ctx.submit(rec).unwrap();
    assert_eq!(ctx.read::<u32>(&b).unwrap(), vec![7; 64]);
    ctx.validation_errors()
}

#[test]
fn a_missing_barrier_is_a_validation_error() {
    assert!(
        fill_then_copy(false) > 0,
        "the read-after-write hazard was not reported"
    );
    assert_eq!(fill_then_copy(true), 0, "a barrier makes the copy safe");
}

/// A discrete GPU's uploads and readbacks go through staging buffers
/// (forced here, where lavapipe would map the memory): a transfer larger
/// than `STAGING_CHUNK_BYTES` goes through one such buffer in chunks, every
/// copy synchronised; the bytes arrive intact, at an offset too, and device
/// memory never holds more than the buffer and one chunk.
#[test]
fn large_transfers_go_through_one_bounded_staging_buffer() {
    let mut ctx = validated();
    ctx.set_host_mapped_transfers(false);
    let chunk_words = (STAGING_CHUNK_BYTES / 4) as usize;
    // One and a half chunks: within lavapipe's 128 MiB buffer limit
    let words = chunk_words + chunk_words / 2 + 1001;
    let mut data: Vec<u32> = (0..words as u32)
        .map(|i| i.wrapping_mul(2_654_435_761))
        .collect();
    let before = ctx.memory_in_use();
    let buf = ctx.upload("test.large", &data).unwrap();
    // A write of more than a chunk at an offset that is not a chunk's
    let patch: Vec<u32> = (0..chunk_words as u32 + 5).map(|i| !i).collect();
    ctx.write(&buf, 4 * 12, &patch).unwrap();
    data[12..12 + patch.len()].copy_from_slice(&patch);
    let back: Vec<u32> = ctx.read(&buf).unwrap();
    assert!(
        back == data,
        "the bytes read back differ from those written"
    );
    let peak = ctx.memory_peak() - before;
    let bytes = 4 * words as u64;
    println!("{bytes} bytes through staging: device memory peaked at {peak}");
    assert!(
        peak <= bytes + STAGING_CHUNK_BYTES,
        "device memory peaked at {peak} bytes for a {bytes}-byte buffer"
    );
    assert_eq!(ctx.validation_errors(), 0);
}
