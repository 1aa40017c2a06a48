//! lancer's folders on the user's machine.

use std::path::PathBuf;

/// lancer's cache folder: `$XDG_CACHE_HOME/lancer`, else `~/.cache/lancer`;
/// `None` when neither variable is set.
pub fn cache_home() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CACHE_HOME")
        .filter(|d| !d.is_empty())
        .map(PathBuf::from)
        .or_else(|| {
            std::env::var_os("HOME")
                .filter(|d| !d.is_empty())
                .map(|h| PathBuf::from(h).join(".cache"))
        })?;
    Some(base.join("lancer"))
}
