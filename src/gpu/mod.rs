//! Packing for the device: the packed structs the kernels read and write
//! ([`structs`], with their std430 layout tests), the one conversion from
//! the CPU scene to them ([`pack`]), the BVH's quantised node pairs
//! ([`bvh_grid`]), textures ([`textures`], [`texture_fit`]) and the
//! rough plastic's coating tables ([`rough_plastic`]).

/// What a device buffer's size grows with. The advice a user gets when a
/// buffer does not fit the device depends on it.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Grows {
    /// Uploaded scene data: the BVH, primitives, materials, emitters, frame.
    Scene,
    /// Uploaded texels of every texture.
    Textures,
    /// This many items per path of the wave.
    Wave(u64),
    /// One item per pixel of the band of rows the device holds.
    Film,
    /// This many items, whatever the scene and the image.
    Fixed(u64),
}

/// How the kernels see a buffer's (first) binding.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Access {
    /// A std430 storage buffer the kernels only read.
    ReadOnly,
    /// A std430 storage buffer the kernels read and write.
    ReadWrite,
    /// An RGBA32UI texel buffer (`texelFetch`).
    Texels,
}

/// One row of the device interface table ([`bindings`]).
#[derive(Debug, Clone, Copy)]
pub struct BufferDecl {
    /// The binding the buffer is declared at.
    pub binding: u32,
    /// A second binding that reads the same buffer as RGBA32UI texels.
    pub texels: Option<u32>,
    /// Bytes of one item of its Rust type.
    pub item_bytes: u64,
    /// How the kernels see `binding`.
    pub access: Access,
    /// What its size grows with.
    pub grows: Grows,
    /// Its allocation and debug name: the pass that writes it, or `scene`.
    pub label: &'static str,
}

/// Turns the table of [`bindings`] into the `BINDING_*` constants,
/// [`bindings::BINDING_COUNT`] and [`bindings::BUFFERS`]. (`build.rs` reads
/// the same table with a macro of its own, for GLSL.)
macro_rules! device_interface {
    ($($(#[$doc:meta])* $name:ident = $binding:literal : $ty:ty,
        $access:ident $decl:literal $(+ texels $tname:ident = $tbinding:literal $tdecl:literal)?,
        grows $grows:ident $(($n:expr))?, $label:literal;)*) => {
        $(
            $(#[$doc])*
            pub const $name: u32 = $binding;
            $(
                #[doc = concat!("The texel view of the buffer at [`", stringify!($name), "`].")]
                pub const $tname: u32 = $tbinding;
            )?
        )*

        /// Every buffer the kernels bind, in the order of the table.
        pub const BUFFERS: &[$crate::gpu::BufferDecl] = &[$(
            $crate::gpu::BufferDecl {
                binding: $binding,
                texels: device_interface!(@texels $($tbinding)?),
                item_bytes: std::mem::size_of::<$ty>() as u64,
                access: device_interface!(@access $access),
                grows: $crate::gpu::Grows::$grows $(($n as u64))?,
                label: $label,
            },
        )*];

        /// Number of descriptor bindings: one past the highest.
        pub const BINDING_COUNT: u32 = {
            let mut count = 0;
            let mut i = 0;
            while i < BUFFERS.len() {
                let b = &BUFFERS[i];
                if b.binding + 1 > count {
                    count = b.binding + 1;
                }
                if let Some(t) = b.texels {
                    if t + 1 > count {
                        count = t + 1;
                    }
                }
                i += 1;
            }
            count
        };
    };
    (@texels) => { None };
    (@texels $t:literal) => { Some($t) };
    (@access readonly) => { $crate::gpu::Access::ReadOnly };
    (@access buffer) => { $crate::gpu::Access::ReadWrite };
    (@access texels) => { $crate::gpu::Access::Texels };
}

pub mod bindings;
pub mod bvh_grid;
pub mod envmap;
pub mod pack;
pub mod rough_plastic;
pub mod structs;
pub mod texture_fit;
pub mod textures;

pub use envmap::GpuEnvironment;
pub use pack::{GpuScene, LightSelection, PackOptions};
pub use structs::*;
pub use textures::{load_texture, pack_textures, GpuTextures, TextureImage};
