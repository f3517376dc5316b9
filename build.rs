//! Build script of the root package.
//!
//! * Link scripts: `-Tlink.x` (cortex-m-rt) and `-Tdefmt.x` (defmt) are passed
//!   only when building for the chip (`target_os = "none"`); a host build
//!   (`cargo test --workspace`) must not see them (TOOLCHAIN pitfall 1).
//!   `memory.x` is copied to `OUT_DIR` and put on the linker search path.
//! * QEMU trace: the `qemu` firmware variant embeds a recorded sensor trace
//!   (`firmware/trace.bin`, written by `host-sim trace`; override with the
//!   environment variable `CABLE_JOINT_TRACE=path`). It is copied to
//!   `OUT_DIR/trace.bin`, which the firmware `include_bytes!`s.

use std::env;
use std::fs;
use std::path::PathBuf;

fn main() {
    let out = PathBuf::from(env::var_os("OUT_DIR").expect("cargo sets OUT_DIR"));
    let manifest = PathBuf::from(env::var_os("CARGO_MANIFEST_DIR").expect("cargo sets it"));
    println!("cargo:rerun-if-changed=build.rs");
    println!("cargo:rerun-if-changed=memory.x");
    println!("cargo:rerun-if-env-changed=CABLE_JOINT_TRACE");

    let target_os = env::var("CARGO_CFG_TARGET_OS").unwrap_or_default();
    if target_os != "none" {
        return;
    }

    fs::copy(manifest.join("memory.x"), out.join("memory.x")).expect("copy memory.x");
    println!("cargo:rustc-link-search={}", out.display());
    println!("cargo:rustc-link-arg-bins=--nmagic");
    println!("cargo:rustc-link-arg-bins=-Tlink.x");
    println!("cargo:rustc-link-arg-bins=-Tdefmt.x");

    // The trace only matters for the qemu variant, but an empty placeholder
    // keeps `include_bytes!` valid in every build.
    let trace_dst = out.join("trace.bin");
    if env::var_os("CARGO_FEATURE_QEMU").is_some() && env::var_os("CARGO_FEATURE_PIL").is_none() {
        let src = env::var_os("CABLE_JOINT_TRACE")
            .map(PathBuf::from)
            .unwrap_or_else(|| manifest.join("firmware").join("trace.bin"));
        println!("cargo:rerun-if-changed={}", src.display());
        if let Err(e) = fs::copy(&src, &trace_dst) {
            panic!(
                "the qemu firmware embeds a sensor trace, but {} cannot be read ({e}); \
                 write it with `cargo run -p host-sim -- trace --out firmware/trace.bin`",
                src.display()
            );
        }
    } else {
        fs::write(&trace_dst, []).expect("write empty trace placeholder");
    }
}
