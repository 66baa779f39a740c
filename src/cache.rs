//! octaray's cache directory, shared by what it keeps between runs (true pictures,
//! parsed meshes), each in a directory of its own under it.

use std::ffi::OsString;
use std::path::PathBuf;

/// `$XDG_CACHE_HOME/octaray`, else `~/.cache/octaray`; `None` when neither variable
/// is set (or is empty).
pub fn root() -> Option<PathBuf> {
    root_from(std::env::var_os("XDG_CACHE_HOME"), std::env::var_os("HOME"))
}

/// [`root`] from the values of `XDG_CACHE_HOME` and `HOME`.
fn root_from(xdg_cache_home: Option<OsString>, home: Option<OsString>) -> Option<PathBuf> {
    let set = |v: Option<OsString>| v.filter(|v| !v.is_empty()).map(PathBuf::from);
    match (set(xdg_cache_home), set(home)) {
        (Some(d), _) => Some(d.join("octaray")),
        (None, Some(h)) => Some(h.join(".cache").join("octaray")),
        (None, None) => None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn xdg_cache_home_comes_first_then_home() {
        let s = |v: &str| Some(OsString::from(v));
        assert_eq!(
            root_from(s("/x/cache"), s("/home/u")),
            Some(PathBuf::from("/x/cache/octaray"))
        );
        assert_eq!(
            root_from(s(""), s("/home/u")),
            Some(PathBuf::from("/home/u/.cache/octaray"))
        );
        assert_eq!(
            root_from(None, s("/home/u")),
            Some(PathBuf::from("/home/u/.cache/octaray"))
        );
        assert_eq!(root_from(None, s("")), None);
        assert_eq!(root_from(None, None), None);
    }
}
