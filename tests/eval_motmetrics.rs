//! Optional cross-check of MOTA and IDF1 against py-motmetrics.
//!
//! Runs `scripts/crosscheck_motmetrics.py` on random cases. When python3 or the
//! `motmetrics` package is missing the test fails and says what to install (scripts/test.sh
//! installs it into `.venv`), unless `MGMOT_ALLOW_MISSING_TOOLS=1` asks for a skip.

use std::process::Command;

/// A cross-check whose tool is missing fails, naming what to install, so that a run without
/// the tool cannot look like a pass; `MGMOT_ALLOW_MISSING_TOOLS=1` turns that into a printed skip
/// for a developer's quick run (scripts/test.sh and CI always provide the tools).
fn missing_tool(test: &str, why: &str) {
    if std::env::var_os("MGMOT_ALLOW_MISSING_TOOLS").is_some_and(|v| v == "1") {
        eprintln!("SKIPPED {test} (MGMOT_ALLOW_MISSING_TOOLS=1): {why}");
    } else {
        panic!(
            "{test} needs a tool that is missing: {why}. scripts/test.sh provides it; \
             set MGMOT_ALLOW_MISSING_TOOLS=1 to skip this check instead"
        );
    }
}

#[test]
fn mota_and_idf1_agree_with_py_motmetrics() {
    let script = concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/scripts/crosscheck_motmetrics.py"
    );
    let out = match Command::new("python3")
        .arg(script)
        .arg("--mgmot")
        .arg(env!("CARGO_BIN_EXE_mgmot"))
        .arg("--cases")
        .arg("20")
        .output()
    {
        Ok(out) => out,
        Err(e) => {
            missing_tool("py-motmetrics cross-check", &format!("python3 ({e})"));
            return;
        }
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(3) {
        missing_tool("py-motmetrics cross-check", stdout.trim());
        return;
    }
    println!("{stdout}");
    assert!(out.status.success(), "{stdout}\n{stderr}");
}
