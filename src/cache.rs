//! octaray's cache directory, shared by what it keeps between runs (true pictures,
//! parsed meshes), each in a directory of its own under it.

use std::ffi::OsString;
use std::path::PathBuf;

/// `$XDG_CACHE_HOME/octaray`, else `~/.cache/octaray`; `None` when neither variable
/// holds an absolute path. An empty or relative value counts as unset (the XDG base
/// directory rules: a relative path is invalid and ignored), so that no run writes a
/// cache under whatever directory it was started in.
pub fn root() -> Option<PathBuf> {
    root_from(std::env::var_os("XDG_CACHE_HOME"), std::env::var_os("HOME"))
}

/// [`root`] from the values of `XDG_CACHE_HOME` and `HOME`.
fn root_from(xdg_cache_home: Option<OsString>, home: Option<OsString>) -> Option<PathBuf> {
    let set = |v: Option<OsString>| v.map(PathBuf::from).filter(|p| p.is_absolute());
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
    fn xdg_cache_home_comes_first_then_home_and_relative_paths_are_ignored() {
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
        // relative values are ignored, each on its own
        assert_eq!(
            root_from(s("relative/cache"), s("/home/u")),
            Some(PathBuf::from("/home/u/.cache/octaray"))
        );
        assert_eq!(
            root_from(s("/x/cache"), s("home")),
            Some(PathBuf::from("/x/cache/octaray"))
        );
        assert_eq!(root_from(s("cache"), s("home")), None);
    }
}
