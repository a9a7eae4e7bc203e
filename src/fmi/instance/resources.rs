//! Resources: the `fmuResourceLocation` URI as a directory and the scene (and the closure
//! `mps pack` computed) read from it.
use crate::physics::world::SetupMemo;
use crate::scene::Scene;
use std::path::{Path, PathBuf};

/// Turns an `fmuResourceLocation` URI into a directory: `file:///abs/path`, `file:/abs/path`
/// and `file://localhost/abs/path`, percent-encoded or not, with or without a trailing '/'.
pub fn resource_dir(uri: &str) -> Result<PathBuf, String> {
    let rest = uri
        .strip_prefix("file://localhost/")
        .map(|r| format!("/{r}"))
        .or_else(|| uri.strip_prefix("file:///").map(|r| format!("/{r}")))
        .or_else(|| {
            uri.strip_prefix("file:/")
                .filter(|r| !r.starts_with('/'))
                .map(|r| format!("/{r}"))
        })
        .ok_or_else(|| {
            format!("fmuResourceLocation '{uri}' is not a local file URI (file:///path)")
        })?;
    let bytes = rest.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        if bytes[i] == b'%' {
            let hex = bytes
                .get(i + 1..i + 3)
                .and_then(|h| std::str::from_utf8(h).ok())
                .and_then(|h| u8::from_str_radix(h, 16).ok())
                .ok_or_else(|| format!("fmuResourceLocation '{uri}' has a bad percent escape"))?;
            out.push(hex);
            i += 3;
        } else {
            out.push(bytes[i]);
            i += 1;
        }
    }
    let s = String::from_utf8(out)
        .map_err(|_| format!("fmuResourceLocation '{uri}' is not UTF-8 once decoded"))?;
    Ok(PathBuf::from(s))
}

/// The default operator's closure as `mps pack` computed it, in an FMU's resources
/// (`SetupMemo::closure_bytes`): an instance's first build takes it instead of computing it.
pub const CLOSURE_FILE: &str = "mps-closure.bin";

/// The closure an FMU ships ([`CLOSURE_FILE`]): a memo holding it; None without the file;
/// Err(why) if it cannot be read or is damaged (the build then computes the closure).
pub fn load_closure(dir: &Path) -> Option<Result<SetupMemo, String>> {
    let path = dir.join(CLOSURE_FILE);
    let bytes = match std::fs::read(&path) {
        Ok(b) => b,
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => return None,
        Err(e) => return Some(Err(format!("cannot read {}: {e}", path.display()))),
    };
    Some(
        SetupMemo::from_closure_bytes(&bytes)
            .map_err(|e| format!("{} is refused: {e}", path.display())),
    )
}

/// Reads and checks the scene of an FMU's resources directory.
pub fn load_scene(dir: &Path) -> Result<Scene, String> {
    let path = dir.join("scene.json");
    let text = std::fs::read_to_string(&path)
        .map_err(|e| format!("cannot read the FMU's scene {}: {e}", path.display()))?;
    // Mesh files (bodies[].shapes[].mesh.file) are relative to the resources folder.
    Scene::from_json_in(&text, Some(dir))
        .map_err(|e| format!("the FMU's scene {} is invalid: {e}", path.display()))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn resource_uris() {
        assert_eq!(
            resource_dir("file:///tmp/a%20b/").unwrap(),
            PathBuf::from("/tmp/a b/")
        );
        assert_eq!(
            resource_dir("file:/tmp/x").unwrap(),
            PathBuf::from("/tmp/x")
        );
        assert_eq!(
            resource_dir("file://localhost/tmp/x").unwrap(),
            PathBuf::from("/tmp/x")
        );
        assert!(resource_dir("http://example/x").is_err());
        assert!(resource_dir("/tmp/x").is_err());
        assert!(resource_dir("file:///tmp/%zz").is_err());
    }
}
