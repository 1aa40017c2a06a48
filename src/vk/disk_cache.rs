//! The persistent pipeline cache: one file per kernel in the user's cache
//! directory, holding the Vulkan pipeline-cache data the driver returned
//! after building it.
//!
//! A file lives at `DIR/<device key>/<kernel key>.bin`. The device key names
//! the vendor, device, driver version and `pipelineCacheUUID`; the kernel key
//! is a hash of the SPIR-V, the specialisation constants, the push-constant
//! size and the binding layout. `DIR` is `$LANCER_PIPELINE_CACHE_DIR`, else
//! `$XDG_CACHE_HOME/lancer/pipelines`, else `~/.cache/lancer/pipelines`;
//! `LANCER_PIPELINE_CACHE_DIR=off` (or empty) turns the cache off.
//!
//! Files are written to a temporary name and renamed, so readers see whole
//! files only. Each starts with a magic, the payload length and its FNV-1a
//! hash; a file that fails that check, or whose Vulkan header (vendor, device,
//! cache UUID) does not match the device, is ignored and rewritten.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, Ordering};

/// Magic at the start of every file: format name and version.
const MAGIC: &[u8; 8] = b"LNCRPC01";
/// Magic, payload length (u64), payload hash (u64).
const HEADER_BYTES: usize = 8 + 8 + 8;

/// 64-bit FNV-1a: a stable hash (the same on every build and platform).
#[derive(Debug, Clone, Copy)]
pub(crate) struct Fnv(u64);

impl Fnv {
    pub(crate) fn new() -> Fnv {
        Fnv(0xcbf2_9ce4_8422_2325)
    }

    pub(crate) fn bytes(mut self, data: &[u8]) -> Fnv {
        for b in data {
            self.0 ^= u64::from(*b);
            self.0 = self.0.wrapping_mul(0x0000_0100_0000_01b3);
        }
        self
    }

    pub(crate) fn u32(self, v: u32) -> Fnv {
        self.bytes(&v.to_le_bytes())
    }

    pub(crate) fn finish(self) -> u64 {
        self.0
    }
}

/// What the persistent cache did while a context built its pipelines.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct PipelineCacheStats {
    /// Pipelines built from a valid file.
    pub loaded: u32,
    /// Files that were there but failed a check (corrupt, truncated, another
    /// device or driver) and were ignored.
    pub rejected: u32,
    /// Files written (after a miss or a rejected file).
    pub stored: u32,
}

/// Counters behind [`PipelineCacheStats`].
#[derive(Debug, Default)]
pub(crate) struct Counters {
    loaded: AtomicU32,
    rejected: AtomicU32,
    stored: AtomicU32,
}

impl Counters {
    pub(crate) fn loaded(&self) {
        self.loaded.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn rejected(&self) {
        self.rejected.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn stored(&self) {
        self.stored.fetch_add(1, Ordering::Relaxed);
    }

    pub(crate) fn snapshot(&self) -> PipelineCacheStats {
        PipelineCacheStats {
            loaded: self.loaded.load(Ordering::Relaxed),
            rejected: self.rejected.load(Ordering::Relaxed),
            stored: self.stored.load(Ordering::Relaxed),
        }
    }
}

/// The cache directory the environment asks for; `None` when turned off or
/// when there is no home directory.
pub(crate) fn default_dir() -> Option<PathBuf> {
    if let Some(dir) = std::env::var_os("LANCER_PIPELINE_CACHE_DIR") {
        let off = dir.is_empty() || dir.eq_ignore_ascii_case("off") || dir == "0";
        return (!off).then(|| PathBuf::from(dir));
    }
    Some(crate::util::dirs::cache_home()?.join("pipelines"))
}

/// The folder of one device and driver under `dir`.
pub(crate) fn device_dir(
    dir: &Path,
    vendor: u32,
    device: u32,
    driver_version: u32,
    uuid: &[u8],
) -> PathBuf {
    let uuid: String = uuid.iter().map(|b| format!("{b:02x}")).collect();
    dir.join(format!(
        "{vendor:04x}-{device:04x}-{driver_version:08x}-{uuid}"
    ))
}

/// Reads a cache file's payload; `Ok(None)` when there is no file,
/// `Err(())` when there is one that fails the envelope check.
pub(crate) fn read(path: &Path) -> Result<Option<Vec<u8>>, ()> {
    let data = match std::fs::read(path) {
        Ok(d) => d,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
        Err(_) => return Err(()),
    };
    if data.len() < HEADER_BYTES || &data[..8] != MAGIC {
        return Err(());
    }
    let word = |i: usize| {
        let mut b = [0u8; 8];
        b.copy_from_slice(&data[i..i + 8]);
        u64::from_le_bytes(b)
    };
    let payload = &data[HEADER_BYTES..];
    if word(8) != payload.len() as u64 || word(16) != Fnv::new().bytes(payload).finish() {
        return Err(());
    }
    Ok(Some(payload.to_vec()))
}

/// Writes `payload` to `path` with its envelope: to a temporary file in the
/// same folder first, then renamed over `path`.
pub(crate) fn write(path: &Path, payload: &[u8]) -> std::io::Result<()> {
    static NEXT: AtomicU32 = AtomicU32::new(0);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(format!(
        ".tmp{}.{}",
        std::process::id(),
        NEXT.fetch_add(1, Ordering::Relaxed)
    ));
    let tmp = PathBuf::from(tmp);
    let mut data = Vec::with_capacity(HEADER_BYTES + payload.len());
    data.extend_from_slice(MAGIC);
    data.extend_from_slice(&(payload.len() as u64).to_le_bytes());
    data.extend_from_slice(&Fnv::new().bytes(payload).finish().to_le_bytes());
    data.extend_from_slice(payload);
    std::fs::write(&tmp, &data)?;
    std::fs::rename(&tmp, path).inspect_err(|_| {
        let _ = std::fs::remove_file(&tmp);
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fnv_matches_the_published_vectors() {
        assert_eq!(Fnv::new().finish(), 0xcbf29ce484222325);
        assert_eq!(Fnv::new().bytes(b"a").finish(), 0xaf63dc4c8601ec8c);
        assert_eq!(Fnv::new().bytes(b"foobar").finish(), 0x85944171f73967e8);
    }

    #[test]
    fn round_trip_and_every_damaged_file_is_rejected() {
        let dir = std::env::temp_dir().join(format!("lancer-disk-cache-{}", std::process::id()));
        let path = dir.join("k.bin");
        assert_eq!(read(&path), Ok(None));
        let payload: Vec<u8> = (0..200u32).map(|i| (i * 7) as u8).collect();
        write(&path, &payload).unwrap();
        assert_eq!(read(&path), Ok(Some(payload.clone())));
        let good = std::fs::read(&path).unwrap();
        // Truncated anywhere, or one bit flipped anywhere: rejected
        for cut in [0, 7, HEADER_BYTES, good.len() - 1] {
            std::fs::write(&path, &good[..cut]).unwrap();
            assert_eq!(read(&path), Err(()), "truncated to {cut} bytes");
        }
        for i in (0..good.len()).step_by(13) {
            let mut bad = good.clone();
            bad[i] ^= 0x10;
            std::fs::write(&path, &bad).unwrap();
            assert_eq!(read(&path), Err(()), "bit flipped at byte {i}");
        }
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
