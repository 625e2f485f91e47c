//! What the examples that time or measure the `simrod` binary share.

use std::path::{Path, PathBuf};

/// `name` in the target directory this example was built into (`target/<profile>/`), so
/// an example measures the binary of its own build profile.
pub fn sibling(name: &str) -> PathBuf {
    let exe = std::env::current_exe().expect("the example's path");
    let dir = exe.parent().and_then(Path::parent).expect("target/<profile>/examples");
    let p = dir.join(name);
    assert!(p.exists(), "{} not built: cargo build -p workbench --bin simrod first", p.display());
    p
}
