//! The autopilot parameter files and the mavlink-router configuration in `firmware-config/`:
//! every parameter file checked against its metadata table (no simulator), a deliberately
//! wrong file reported line by line, and the router configuration read as INI.

use mgmot::firmware::{check_file, Autopilot, ParamTable, ARDUPILOT_COPTER_TABLE, PX4_TABLE};
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use crate::common::{mgmot, repo_file, TestDir};

fn root() -> PathBuf {
    repo_file("firmware-config")
}

fn files_in(dir: &Path) -> Vec<PathBuf> {
    let mut files: Vec<PathBuf> = std::fs::read_dir(dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.expect("directory entry").path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    files
}

fn check_all(autopilot: Autopilot, dir: &str, table: &str) -> usize {
    let table = ParamTable::parse(table).expect("shipped table parses");
    let files = files_in(&root().join(dir));
    assert!(!files.is_empty(), "no files in firmware-config/{dir}");
    let mut report = Vec::new();
    for f in &files {
        for p in check_file(autopilot, f, &table).expect("readable") {
            report.push(format!("{}:{}", f.display(), p));
        }
    }
    assert!(report.is_empty(), "problems:\n{}", report.join("\n"));
    files.len()
}

#[test]
fn ardupilot_files_match_the_arducopter_table() {
    assert_eq!(
        check_all(Autopilot::ArduPilot, "ardupilot", ARDUPILOT_COPTER_TABLE),
        2
    );
}

#[test]
fn px4_files_match_the_px4_table() {
    assert_eq!(check_all(Autopilot::Px4, "px4", PX4_TABLE), 1);
}

#[test]
fn a_wrong_file_is_reported_line_by_line() {
    let dir = TestDir::new();
    let ap = dir.join("wrong.parm");
    std::fs::write(
        &ap,
        "# wrong on purpose\nSERIAL2_PROTOCOL 2\nSERIAL2_BOUD 921\nSERIAL2_BAUD 921.5\n\
         MNT1_PITCH_MIN -120\nMNT1_TYPE 99\nMNT1_PITCH_MAX 1000000\n",
    )
    .expect("write");
    let table = ParamTable::parse(ARDUPILOT_COPTER_TABLE).expect("table");
    let problems = check_file(Autopilot::ArduPilot, &ap, &table).expect("readable");
    let got: Vec<(usize, String)> = problems.iter().map(|p| (p.line, p.to_string())).collect();
    assert_eq!(
        got.iter().map(|(l, _)| *l).collect::<Vec<_>>(),
        vec![3, 4, 5, 6, 7],
        "{got:?}"
    );
    assert!(
        got[0].1.contains("SERIAL2_BOUD: not a parameter"),
        "{got:?}"
    );
    assert!(got[1].1.contains("not an integer (int32"), "{got:?}");
    assert!(got[2].1.contains("below the minimum -90"), "{got:?}");
    assert!(
        got[3].1.contains("not one of the documented values"),
        "{got:?}"
    );
    assert!(got[4].1.contains("does not fit int16"), "{got:?}");

    let px4 = dir.join("wrong.params");
    std::fs::write(
        &px4,
        "1\t1\tMAV_1_CONFIG\t102\t6\n1\t1\tMAV_9_MODE\t2\t6\n1\t1\tMAV_1_RATE\t0.5\t6\n\
         1\t1\tMNT_RATE_YAW\t30\t6\n1\t1\tMAV_1_MODE\t-1\t6\n",
    )
    .expect("write");
    let table = ParamTable::parse(PX4_TABLE).expect("table");
    let problems = check_file(Autopilot::Px4, &px4, &table).expect("readable");
    let got: Vec<String> = problems.iter().map(|p| p.to_string()).collect();
    assert_eq!(got.len(), 4, "{got:?}");
    assert!(
        got[0].starts_with("line 2: MAV_9_MODE: not a parameter"),
        "{got:?}"
    );
    assert!(got[1].starts_with("line 3: MAV_1_RATE:") && got[1].contains("not an integer"));
    assert!(
        got[2].starts_with("line 4: MNT_RATE_YAW: type column"),
        "{got:?}"
    );
    assert!(got[3].starts_with("line 5: MAV_1_MODE:") && got[3].contains("documented values"));

    // The command line says the same, as FILE:LINE, and fails.
    let out = mgmot()
        .args(["firmware-check", "--autopilot", "ardupilot"])
        .arg(&ap)
        .output();
    assert!(!out.status.success());
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(&format!("{}:3: SERIAL2_BOUD", ap.display())),
        "{stdout}"
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("5 problem(s)"));
}

#[test]
fn the_command_accepts_the_shipped_files() {
    for (autopilot, dir) in [("ardupilot", "ardupilot"), ("px4", "px4")] {
        let out = mgmot()
            .args(["firmware-check", "--autopilot", autopilot])
            .args(files_in(&root().join(dir)))
            .output();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.lines().all(|l| l.ends_with(": ok")), "{stdout}");
    }
}

/// A minimal reader of mavlink-router's INI dialect: `[Section name]`, `Key = Value`, `#`
/// comments; keys are case-insensitive (lower-cased here).
fn read_ini(text: &str) -> Result<BTreeMap<String, BTreeMap<String, String>>, String> {
    let mut sections: BTreeMap<String, BTreeMap<String, String>> = BTreeMap::new();
    let mut current: Option<String> = None;
    for (i, raw) in text.lines().enumerate() {
        let line = raw.trim();
        if line.is_empty() || line.starts_with('#') || line.starts_with(';') {
            continue;
        }
        if let Some(name) = line.strip_prefix('[').and_then(|l| l.strip_suffix(']')) {
            let name = name.split_whitespace().collect::<Vec<_>>().join(" ");
            if sections.insert(name.clone(), BTreeMap::new()).is_some() {
                return Err(format!("line {}: section [{name}] twice", i + 1));
            }
            current = Some(name);
            continue;
        }
        let (key, value) = line
            .split_once('=')
            .ok_or_else(|| format!("line {}: not `key = value`: {line:?}", i + 1))?;
        let section = current
            .as_ref()
            .and_then(|c| sections.get_mut(c))
            .ok_or_else(|| format!("line {}: key outside a section", i + 1))?;
        section.insert(key.trim().to_lowercase(), value.trim().to_owned());
    }
    Ok(sections)
}

#[test]
fn mavlink_router_config_has_the_three_endpoints() {
    let path = root().join("mavlink-router/main.conf");
    let text = std::fs::read_to_string(&path).expect("main.conf");
    let ini = read_ini(&text).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let get = |section: &str, key: &str| -> &str {
        ini.get(section)
            .and_then(|s| s.get(key))
            .map(String::as_str)
            .unwrap_or_else(|| panic!("[{section}] {key} missing"))
    };
    assert_eq!(
        ini.keys().map(String::as_str).collect::<Vec<_>>(),
        [
            "General",
            "UartEndpoint autopilot",
            "UdpEndpoint gcs",
            "UdpEndpoint mgmot"
        ]
    );
    assert_eq!(get("UartEndpoint autopilot", "baud"), "921600");
    assert!(get("UartEndpoint autopilot", "device").starts_with("/dev/"));
    assert_eq!(get("UdpEndpoint gcs", "mode"), "Server");
    assert_eq!(get("UdpEndpoint gcs", "port"), "14550");
    assert_eq!(get("UdpEndpoint mgmot", "mode"), "Normal");
    assert_eq!(get("UdpEndpoint mgmot", "address"), "127.0.0.1");
    let port = get("UdpEndpoint mgmot", "port");
    // mgmot's side of it: the connection string the README tells mgmot to use parses.
    mgmot::mavlink::parse_connection(&format!("udpin:127.0.0.1:{port}"))
        .expect("mgmot connection string");
    assert!(read_ini("[General]\nno equals sign\n").is_err());

    // The same baud rate everywhere: router, ArduPilot (SERIAL2_BAUD 921 = 921600), PX4.
    let parm = std::fs::read_to_string(root().join("ardupilot/mgmot.parm")).expect("parm");
    assert!(parm.lines().any(|l| l.trim() == "SERIAL2_BAUD 921"));
    let params = std::fs::read_to_string(root().join("px4/mgmot.params")).expect("params");
    assert!(params
        .lines()
        .any(|l| l == "1\t1\tSER_TEL2_BAUD\t921600\t6"));
}
