//! The validation layer checks synchronisation too: a missing barrier
//! between two commands is counted as a validation error (the test suite
//! asserts zero of them on every render).

use lancer::internal::vk::{Context, ContextOptions, MemoryKind};

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
