//! Generates the Rust bindings of the project's MAVLink dialect
//! (`firmware-config/mavlink/mgmot.xml`) with `mavlink-bindgen`, the generator the `mavlink`
//! crate itself uses.
//!
//! The dialect includes `common.xml`, `development.xml` and `ardupilotmega.xml`. Those standard
//! definitions (and what they include) are kept beside `mgmot.xml` in this repository, copied
//! unchanged from the `mavlink` crate's package at the version pinned in Cargo.toml
//! (`firmware-config/mavlink/README.md` lists them; `wire/tests/definitions.rs` fails if they
//! drift from the package in use). The build therefore reads only files of this package: it
//! does not depend on which packages happen to be in the local cargo registry and never runs
//! cargo or touches the network. `MGMOT_MAVLINK_DEFINITIONS` (a directory with `common.xml`
//! and its includes) replaces the kept standard files, for trying newer definitions.

use std::path::{Path, PathBuf};

/// The dialect, relative to this package's root (the repository's `firmware-config/`).
const DIALECT_XML: &str = "../firmware-config/mavlink/mgmot.xml";

/// The standard definitions the dialect includes, directly or through another file; kept beside
/// the dialect.
const STANDARD_XML: &[&str] = &[
    "common.xml",
    "development.xml",
    "ardupilotmega.xml",
    "standard.xml",
    "minimal.xml",
    "uAvionix.xml",
    "icarous.xml",
    "loweheiser.xml",
    "cubepilot.xml",
    "csAirLink.xml",
];

/// The module declaration of the generated dialect, with the lints generated code cannot meet.
const DECLARATION: &str =
    "/// The mgmot MAVLink dialect (common + development + ardupilotmega + mgmot.xml),\n\
/// generated from `firmware-config/mavlink/mgmot.xml` at build time.\n\
#[allow(missing_docs, deprecated, unexpected_cfgs, unused_imports, non_camel_case_types,\n\
non_snake_case, clippy::all, clippy::pedantic, rustdoc::all)]\n\
pub mod mgmot;\n";

fn main() {
    if let Err(e) = generate() {
        // A build script reports failure through its exit status; the message goes to cargo.
        eprintln!("error: generating the mgmot MAVLink dialect: {e}");
        std::process::exit(1);
    }
}

fn generate() -> Result<(), String> {
    let manifest_dir = PathBuf::from(env("CARGO_MANIFEST_DIR")?);
    let out_dir = PathBuf::from(env("OUT_DIR")?);
    let dialect = manifest_dir.join(DIALECT_XML);
    let kept = dialect
        .parent()
        .ok_or_else(|| format!("{}: no parent directory", dialect.display()))?
        .to_path_buf();
    println!("cargo:rerun-if-changed={}", dialect.display());
    println!("cargo:rerun-if-changed=build.rs");
    // The generated code has `cfg(feature = ...)` switches for features of the `mavlink` crate
    // that this crate does not have (they stay off here); declare them so they are expected.
    println!("cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\"))");
    println!("cargo:rerun-if-env-changed=MGMOT_MAVLINK_DEFINITIONS");
    // tests/definitions.rs asks cargo where the `mavlink` package of this target is.
    println!("cargo:rustc-env=MGMOT_BUILD_TARGET={}", env("TARGET")?);

    let standard = match std::env::var_os("MGMOT_MAVLINK_DEFINITIONS") {
        Some(dir) => PathBuf::from(dir),
        None => kept,
    };
    // The generator resolves `<include>` relative to the including file, so the dialect and the
    // standard files are staged side by side in OUT_DIR.
    let staging = out_dir.join("mavlink-definitions");
    std::fs::create_dir_all(&staging).map_err(|e| format!("{}: {e}", staging.display()))?;
    for name in STANDARD_XML {
        let from = standard.join(name);
        println!("cargo:rerun-if-changed={}", from.display());
        copy(&from, &staging.join(name)).map_err(|e| {
            format!(
                "{e} (the standard MAVLink definitions belong beside {DIALECT_XML}; \
                 MGMOT_MAVLINK_DEFINITIONS may name another directory holding them)"
            )
        })?;
    }
    let staged_dialect = staging.join("mgmot.xml");
    copy(&dialect, &staged_dialect)?;

    let bindings_dir = out_dir.join("mavlink-bindings");
    std::fs::create_dir_all(&bindings_dir)
        .map_err(|e| format!("{}: {e}", bindings_dir.display()))?;
    mavlink_bindgen::generate(
        mavlink_bindgen::XmlDefinitions::Files(vec![staged_dialect]),
        &bindings_dir,
    )
    .map_err(|e| format!("{}: {e}", dialect.display()))?;
    // The generated module starts with inner attributes, so it has to be a module file of its
    // own: this declaration is `include!`d by src/dialect.rs and names it.
    let declaration = bindings_dir.join("declare.rs");
    std::fs::write(&declaration, DECLARATION)
        .map_err(|e| format!("{}: {e}", declaration.display()))?;
    Ok(())
}

fn env(key: &str) -> Result<String, String> {
    std::env::var(key).map_err(|_| format!("{key} is not set (not run by cargo?)"))
}

fn copy(from: &Path, to: &Path) -> Result<(), String> {
    std::fs::copy(from, to)
        .map(|_| ())
        .map_err(|e| format!("copying {} to {}: {e}", from.display(), to.display()))
}
