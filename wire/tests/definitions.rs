//! The standard MAVLink definitions kept beside `firmware-config/mavlink/mgmot.xml` (which
//! this crate's build.rs generates the dialect from) must be the ones of the `mavlink` package in use:
//! the messages the `mavlink` crate decodes and the ones mgmot's dialect decodes then agree.
//! When the crate is upgraded, this test names every file to copy again.

use std::path::{Path, PathBuf};
use std::process::Command;

/// Where the definitions sit inside the `mavlink` crate's package.
const DEFINITIONS_IN_PACKAGE: &str = "mavlink/message_definitions/v1.0";

/// The kept copies: the files the dialect includes, directly or through another file.
const KEPT: &[&str] = &[
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

/// The `mavlink` package's source directory, as cargo resolved it for this build's target.
fn mavlink_package_dir() -> PathBuf {
    let cargo = std::env::var("CARGO").unwrap_or_else(|_| "cargo".to_owned());
    // The workspace's manifest: the `mavlink` package is resolved for the whole workspace.
    let manifest = Path::new(env!("CARGO_MANIFEST_DIR")).join("../Cargo.toml");
    // The test binary was built, so every package of this target is on disk: no network.
    let output = Command::new(cargo)
        .args(["metadata", "--format-version", "1", "--offline"])
        .args(["--filter-platform", env!("MGMOT_BUILD_TARGET")])
        .arg("--manifest-path")
        .arg(&manifest)
        .output()
        .expect("running cargo metadata");
    assert!(
        output.status.success(),
        "cargo metadata failed: {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let meta: serde_json::Value = serde_json::from_slice(&output.stdout).expect("metadata JSON");
    let packages = meta["packages"].as_array().expect("packages");
    let mavlink: Vec<&serde_json::Value> =
        packages.iter().filter(|p| p["name"] == "mavlink").collect();
    assert_eq!(
        mavlink.len(),
        1,
        "exactly one `mavlink` package in the build"
    );
    let path = mavlink[0]["manifest_path"].as_str().expect("manifest_path");
    Path::new(path).parent().expect("package dir").to_path_buf()
}

#[test]
fn kept_standard_definitions_match_the_mavlink_package() {
    let package = mavlink_package_dir().join(DEFINITIONS_IN_PACKAGE);
    let kept = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware-config/mavlink");
    let mut drifted = Vec::new();
    for name in KEPT {
        let ours = std::fs::read(kept.join(name)).expect("kept definition file");
        let theirs = std::fs::read(package.join(name)).expect("package definition file");
        if ours != theirs {
            drifted.push(*name);
        }
    }
    assert!(
        drifted.is_empty(),
        "these kept MAVLink definitions differ from {}: {drifted:?}; copy them again",
        package.display()
    );
}

#[test]
fn kept_files_are_the_whole_include_closure_of_the_dialect() {
    // Every <include> of the dialect and of the kept files is itself kept, and nothing more,
    // so the build never needs a file from elsewhere and no stale copy lingers.
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../firmware-config/mavlink");
    let mut seen = std::collections::BTreeSet::new();
    let mut todo = vec!["mgmot.xml".to_owned()];
    while let Some(name) = todo.pop() {
        let text = std::fs::read_to_string(dir.join(&name)).expect("definition file");
        for part in text.split("<include>").skip(1) {
            let included = part.split("</include>").next().expect("closing tag").trim();
            if seen.insert(included.to_owned()) {
                todo.push(included.to_owned());
            }
        }
    }
    let kept: std::collections::BTreeSet<String> = KEPT.iter().map(|s| (*s).to_owned()).collect();
    assert_eq!(seen, kept);
    let on_disk: std::collections::BTreeSet<String> = std::fs::read_dir(&dir)
        .expect("firmware-config/mavlink")
        .filter_map(|e| e.ok())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".xml") && n != "mgmot.xml")
        .collect();
    assert_eq!(
        on_disk, kept,
        "firmware-config/mavlink holds exactly the kept files"
    );
}
