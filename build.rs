//! Generates the Rust bindings of the project's MAVLink dialect
//! (`firmware-config/mavlink/mgmot.xml`) with `mavlink-bindgen`, the generator the `mavlink`
//! crate itself uses.
//!
//! The dialect includes `common.xml`, `development.xml` and `ardupilotmega.xml`. Those standard
//! definitions are not copied into this repository: they ship inside the `mavlink` crate's
//! package (`<package>/mavlink/message_definitions/v1.0/`), which is a dependency of this crate.
//! `cargo metadata` (run offline, for the target being built, on the resolved lock file) tells where that package's
//! sources are; `MGMOT_MAVLINK_DEFINITIONS` (a directory) overrides the lookup. The standard
//! files and `mgmot.xml` are staged side by side in `OUT_DIR` (the generator resolves
//! `<include>` relative to the including file) and `OUT_DIR/mgmot.rs` is generated from them.

use std::path::{Path, PathBuf};
use std::process::Command;

/// The dialect, relative to the package root.
const DIALECT_XML: &str = "firmware-config/mavlink/mgmot.xml";

/// Where the definitions sit inside the `mavlink` crate's package.
const DEFINITIONS_IN_PACKAGE: &str = "mavlink/message_definitions/v1.0";

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
    println!("cargo:rerun-if-changed={}", dialect.display());
    println!("cargo:rerun-if-changed=build.rs");
    // The generated code has `cfg(feature = ...)` switches for features of the `mavlink` crate
    // that this crate does not have (they stay off here); declare them so they are expected.
    println!("cargo::rustc-check-cfg=cfg(feature, values(\"serde\", \"arbitrary\", \"ts-rs\"))");
    println!("cargo:rerun-if-env-changed=MGMOT_MAVLINK_DEFINITIONS");

    let standard = match std::env::var_os("MGMOT_MAVLINK_DEFINITIONS") {
        Some(dir) => PathBuf::from(dir),
        None => mavlink_package_dir(&manifest_dir)?.join(DEFINITIONS_IN_PACKAGE),
    };
    let staging = out_dir.join("mavlink-definitions");
    std::fs::create_dir_all(&staging).map_err(|e| format!("{}: {e}", staging.display()))?;
    let entries = std::fs::read_dir(&standard).map_err(|e| {
        format!(
            "{}: {e} (set MGMOT_MAVLINK_DEFINITIONS to a directory with common.xml)",
            standard.display()
        )
    })?;
    for entry in entries {
        let path = entry.map_err(|e| e.to_string())?.path();
        if path.extension().is_some_and(|x| x == "xml") {
            if let Some(name) = path.file_name() {
                copy(&path, &staging.join(name))?;
            }
        }
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
    // own: this declaration is `include!`d by src/mavlink/mod.rs and names it.
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

/// The source directory of the `mavlink` package this crate depends on.
fn mavlink_package_dir(manifest_dir: &Path) -> Result<PathBuf, String> {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    // Only the packages of the target being built: the others (other platforms) may not have
    // been downloaded, and the lookup must not touch the network.
    let target = env("TARGET")?;
    let output = Command::new(cargo)
        .args([
            "metadata",
            "--format-version",
            "1",
            "--offline",
            "--filter-platform",
        ])
        .arg(target)
        .arg("--manifest-path")
        .arg(manifest_dir.join("Cargo.toml"))
        .output()
        .map_err(|e| format!("running cargo metadata: {e}"))?;
    if !output.status.success() {
        return Err(format!(
            "cargo metadata failed: {}",
            String::from_utf8_lossy(&output.stderr)
        ));
    }
    let meta: serde_json::Value = serde_json::from_slice(&output.stdout)
        .map_err(|e| format!("cargo metadata output: {e}"))?;
    let packages = meta["packages"]
        .as_array()
        .ok_or("cargo metadata: no packages")?;
    let manifest = packages
        .iter()
        .filter(|p| p["name"] == "mavlink")
        .filter_map(|p| p["manifest_path"].as_str())
        .next()
        .ok_or("cargo metadata: the `mavlink` package is not among the dependencies")?;
    Path::new(manifest)
        .parent()
        .map(Path::to_path_buf)
        .ok_or_else(|| format!("{manifest}: no parent directory"))
}
