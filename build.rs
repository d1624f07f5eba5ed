//! Build script: embeds an rpath to MuJoCo's shared library so that the binary and the tests
//! run with no LD_LIBRARY_PATH, and fails early with instructions when the library is missing.

use std::path::PathBuf;

fn main() {
    println!("cargo::rerun-if-env-changed=MUJOCO_DYNAMIC_LINK_DIR");
    println!("cargo::rerun-if-changed=build.rs");
    let Some(dir) = std::env::var_os("MUJOCO_DYNAMIC_LINK_DIR") else {
        // mujoco-rs will look for MuJoCo by its own means (pkg-config); nothing to add.
        return;
    };
    let dir = PathBuf::from(dir);
    if !dir.join("libmujoco.so").exists() {
        panic!(
            "\n\nMuJoCo 3.17.0 was not found in {}.\n\
             Run `make setup` (or scripts/setup-mujoco.sh) to fetch it from the `mujoco` wheel \
             on PyPI, or set MUJOCO_DYNAMIC_LINK_DIR to the absolute path of a folder holding \
             libmujoco.so from MuJoCo 3.17.0.\n\n",
            dir.display()
        );
    }
    println!("cargo::rustc-link-arg=-Wl,-rpath,{}", dir.display());
}
