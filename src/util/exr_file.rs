//! Reading OpenEXR files as linear RGB, with every size in the header
//! checked before a pixel is read: for textures and environment maps
//! (`gpu`) and for the images `compare` and `converge` read (`io`).

use std::path::Path;

use anyhow::{ensure, Context, Result};

/// The most bytes one block (a tile, or a run of scan lines) of an OpenEXR
/// file may hold uncompressed: 256 MiB, a block the size of the largest
/// texture lancer reads (4096 x 4096 texels of four 32-bit channels). The
/// decoder reserves a block's bytes from the size its chunk claims, so a
/// header whose blocks may be larger lets a file of a few hundred bytes
/// claim gigabytes.
pub const MAX_EXR_BLOCK_BYTES: u64 = 1 << 28;

/// Checks every block an OpenEXR file's headers describe against
/// [`MAX_EXR_BLOCK_BYTES`], in checked arithmetic, before any pixel is
/// read. `what` names the file in the message.
pub fn check_exr_blocks(meta: &exr::meta::MetaData, what: &str) -> Result<()> {
    for header in &meta.headers {
        let (kind, width, height) = match header.blocks {
            exr::meta::BlockDescription::Tiles(tiles) => {
                ("tile", tiles.tile_size.width(), tiles.tile_size.height())
            }
            exr::meta::BlockDescription::ScanLines => (
                "block of scan lines",
                header.layer_size.width(),
                header.compression.scan_lines_per_block(),
            ),
        };
        let bytes = (width as u64)
            .checked_mul(height as u64)
            .and_then(|pixels| pixels.checked_mul(header.channels.bytes_per_pixel as u64));
        ensure!(
            bytes.is_some_and(|b| b <= MAX_EXR_BLOCK_BYTES),
            "{what}: its {kind} of {width} x {height} pixels with {} channels holds {} bytes; \
             lancer reads OpenEXR files whose blocks hold at most {MAX_EXR_BLOCK_BYTES} bytes \
             (256 MiB): save it with smaller tiles or fewer channels",
            header.channels.list.len(),
            bytes.map_or_else(|| String::from("more than 2^64"), |b| b.to_string())
        );
    }
    Ok(())
}

/// Reads an OpenEXR file as linear RGB: returns `(width, height, rgb)` with
/// `rgb` row-major, top row first, 3 floats per pixel. The image is the
/// file's display window; the pixels its data window stores are placed in
/// it, and any part of the display window the data window does not cover
/// is black. An alpha channel, if any, is dropped. Errors name `path`.
///
/// The pixels are decoded straight into the returned buffer, one block at a
/// time, so the image is held once (a general decoder holds it three times:
/// its own buffer with alpha, a copy, and the RGB conversion).
pub fn read_exr(path: &Path) -> Result<(u32, u32, Vec<f32>)> {
    use exr::prelude::{ReadChannels as _, ReadLayers as _};
    let cannot = || format!("{}: cannot decode OpenEXR image", path.display());
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .with_context(|| format!("{}: not a readable OpenEXR file", path.display()))?;
    check_exr_blocks(&meta, &path.display().to_string())?;
    // The layer read: the first with R, G and B channels, as the reader's
    // `first_valid_layer` below picks it
    let has =
        |h: &exr::meta::header::Header, name: &str| h.channels.list.iter().any(|c| c.name.eq(name));
    let header = (meta.headers.iter())
        .find(|h| has(h, "R") && has(h, "G") && has(h, "B"))
        .with_context(|| format!("{}: no layer has R, G and B channels", path.display()))?;
    let display = header.shared_attributes.display_window;
    let (width, height) = (display.size.width(), display.size.height());
    let too_large = || {
        format!(
            "{}: display window of {width} x {height} pixels is too large",
            path.display()
        )
    };
    let w32 = u32::try_from(width).ok().with_context(too_large)?;
    let h32 = u32::try_from(height).ok().with_context(too_large)?;
    let floats = (width.checked_mul(height))
        .and_then(|n| n.checked_mul(3))
        .with_context(too_large)?;
    // Where the data window's pixel (0, 0) lies in the display window
    let offset = header.own_attributes.layer_position - display.position;
    let (dx, dy) = (i64::from(offset.x()), i64::from(offset.y()));
    let image = exr::prelude::read()
        .no_deep_data()
        .largest_resolution_level()
        .rgba_channels(
            move |_, _| vec![0f32; floats],
            move |rgb: &mut Vec<f32>,
                  at: exr::math::Vec2<usize>,
                  (r, g, b, _): (f32, f32, f32, f32)| {
                let x = at.x() as i64 + dx;
                let y = at.y() as i64 + dy;
                if (0..width as i64).contains(&x) && (0..height as i64).contains(&y) {
                    let i = 3 * (y as usize * width + x as usize);
                    rgb[i..i + 3].copy_from_slice(&[r, g, b]);
                }
            },
        )
        .first_valid_layer()
        .all_attributes()
        .non_parallel()
        .from_file(path)
        .with_context(cannot)?;
    Ok((w32, h32, image.layer_data.channel_data.pixels))
}
