//! Cross-check of MOTA and IDF1 against py-motmetrics.
//!
//! Runs `scripts/crosscheck_motmetrics.py` on random cases. When python3 or the `motmetrics`
//! package is missing the test fails and says what to install (scripts/test.sh installs it
//! into `.venv`): a missing tool never passes as a skip.

use crate::common;

use common::{missing_tool, require_python};
use std::process::Command;

#[test]
fn mota_and_idf1_agree_with_py_motmetrics() {
    const TEST: &str = "py-motmetrics cross-check";
    require_python(TEST, &["numpy", "motmetrics"]);
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
        Err(e) => missing_tool(TEST, &format!("python3 ({e})")),
    };
    let stdout = String::from_utf8_lossy(&out.stdout);
    let stderr = String::from_utf8_lossy(&out.stderr);
    if out.status.code() == Some(3) {
        missing_tool(TEST, stdout.trim());
    }
    println!("{stdout}");
    assert!(out.status.success(), "{stdout}\n{stderr}");
}
