//! Loading a float texture holds it at most about twice: an EXR is decoded
//! straight into linear RGB, float texels become device words in place, and
//! the device words have their room from the start. A texture at the size
//! limit (4096 x 4096 texels, which an EXR file of a few hundred bytes can
//! claim) then needs about 0.4 GB at its peak, where it needed 0.6 GB.
//!
//! The peak is measured by this test binary's allocator, which counts the
//! bytes held; the binary holds this one test, so that no other test
//! allocates while it measures.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};

/// The system allocator, counting the bytes held and their peak.
struct Counting;

static HELD: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

// SAFETY: every call is passed to the system allocator unchanged; the
// counters only observe sizes.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        // SAFETY: the caller's contract is the system allocator's.
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            let held = HELD.fetch_add(layout.size(), Ordering::SeqCst) + layout.size();
            PEAK.fetch_max(held, Ordering::SeqCst);
        }
        p
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        // SAFETY: as above.
        unsafe { System.dealloc(ptr, layout) };
        HELD.fetch_sub(layout.size(), Ordering::SeqCst);
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        // SAFETY: as above.
        let p = unsafe { System.realloc(ptr, layout, new_size) };
        if !p.is_null() {
            // The old and the new block may both be held while it moves
            let held = HELD.fetch_add(new_size, Ordering::SeqCst) + new_size;
            PEAK.fetch_max(held, Ordering::SeqCst);
            HELD.fetch_sub(layout.size(), Ordering::SeqCst);
        }
        p
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Writes an RGBA float EXR of `width` x `height` texels, with a scene of
/// one sphere textured by it, in `dir`.
fn textured_scene(dir: &std::path::Path, width: usize, height: usize) -> lancer::scene::Scene {
    use exr::prelude::*;
    let layer = Layer::new(
        Vec2(width, height),
        LayerAttributes::named("rgba"),
        Encoding::FAST_LOSSLESS,
        SpecificChannels::rgba(|p: Vec2<usize>| {
            let v = (p.x() + width * p.y()) as f32 / (width * height) as f32;
            (v, 1.0 - v, 0.5f32, 1.0f32)
        }),
    );
    Image::from_layer(layer)
        .write()
        .to_file(dir.join("float.exr"))
        .unwrap();
    let text = "[render]\nwidth = 8\nheight = 8\nspp = 1\n\
                [camera]\neye = [0, 0, 5]\nlook_at = [0, 0, 0]\nvfov = 40\n\
                [materials.m]\ntype = \"lambert\"\nalbedo_texture = \"float.exr\"\n\
                [[objects]]\ntype = \"sphere\"\ncenter = [0, 0, 0]\nradius = 0.5\n\
                material = \"m\"\n";
    lancer::scene::load_str(text, &dir.join("scene.toml")).unwrap()
}

/// The bytes `pack_textures` holds at its peak, above what was held
/// before, packing `scene` into `max_bytes`; and the words it packed.
fn packing_peak(scene: &lancer::scene::Scene, max_bytes: u64) -> (usize, usize) {
    let before = HELD.load(Ordering::SeqCst);
    PEAK.store(before, Ordering::SeqCst);
    let packed = lancer::internal::gpu::pack_textures(scene, max_bytes).unwrap();
    (PEAK.load(Ordering::SeqCst) - before, packed.words.len())
}

/// Packing a float texture peaks at most 2.5 times its RGB floats above
/// what was held before:
/// - a 1024 x 1024 RGBA EXR, packed whole (2.01 times measured); it peaked
///   at 3.0 times when the general decoder's RGBA buffer, its copy and the
///   RGB conversion were held at once;
/// - a 1048576 x 1 one, shrunk to fit a binding of 8 MiB: its filter's
///   table of weights, one vector per output texel, and two rows of
///   partial sums took more than the texture (the texture fuzz target's
///   finding, at 16.8 million texels).
///
/// The two run in one test, one after the other, so that nothing else
/// allocates while each is measured.
#[test]
fn a_float_texture_is_held_at_most_about_twice_while_it_is_packed() {
    let dir = tempfile::tempdir().unwrap();
    for (width, height, max_bytes) in [(1024, 1024, 1 << 27), (1 << 20, 1, 1 << 23)] {
        let scene = textured_scene(dir.path(), width, height);
        let (peak, words) = packing_peak(&scene, max_bytes);
        let rgb_bytes = (width * height * 3 * 4) as f64;
        if max_bytes == 1 << 27 {
            assert_eq!(
                words,
                4 + width * height * 3,
                "every texel packed, none shrunk"
            );
        } else {
            assert!(
                words * 4 <= max_bytes as usize && words < 4 + width * 3,
                "{words}"
            );
        }
        let ratio = peak as f64 / rgb_bytes;
        println!("{width} x {height}: peak {peak} bytes = {ratio:.2} x its {rgb_bytes} bytes of RGB floats");
        assert!(
            ratio <= 2.5,
            "packing {width} x {height} held {peak} bytes at its peak, {ratio:.2} x its RGB floats"
        );
    }
}
