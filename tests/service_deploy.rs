//! Issue 11, part 3: the deployment. `scripts/install.sh` into a temporary `DESTDIR` with
//! `--no-system` (no user, no chown, no systemctl): the files, the stripped binary and its
//! split-off debug info, the paths under another `--prefix`, an upgrade that keeps the
//! configuration, `--uninstall` (keeps configuration and flight data) and `--purge`. And the
//! detector under the unit's `MemoryDenyWriteExecute=`.

use crate::common;

use common::{missing_tool, repo_file, TestCommand, TestDir};
use std::os::unix::fs::PermissionsExt;
use std::os::unix::process::CommandExt;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Duration;

/// `scripts/install.sh ARGS` with `DESTDIR=root`, files only; fails the test if it fails.
fn install(root: &Path, args: &[&str]) -> String {
    let out = TestCommand::new("bash")
        .arg(repo_file("scripts/install.sh"))
        .args(["--no-system"])
        .args(args)
        .env("DESTDIR", root)
        .env_remove("ORT_DYLIB_PATH")
        .output_within(Duration::from_secs(120), "scripts/install.sh");
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "install.sh {args:?}: {}\n{stdout}{}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Every file under `dir`, relative to it, sorted.
fn files(dir: &Path) -> Vec<String> {
    fn walk(base: &Path, dir: &Path, out: &mut Vec<String>) {
        let Ok(entries) = std::fs::read_dir(dir) else {
            return;
        };
        for e in entries {
            let path = e.unwrap().path();
            if path.is_dir() {
                walk(base, &path, out);
            } else {
                out.push(path.strip_prefix(base).unwrap().display().to_string());
            }
        }
    }
    let mut out = Vec::new();
    walk(dir, dir, &mut out);
    out.sort();
    out
}

fn contains(haystack: &[u8], needle: &[u8]) -> bool {
    haystack.windows(needle.len()).any(|w| w == needle)
}

/// The section names of a 64-bit little-endian ELF file (the string ".debug_info" also occurs
/// in std's backtrace code, so the section table is what tells).
fn elf_sections(elf: &[u8]) -> Vec<String> {
    assert!(
        elf.starts_with(b"\x7fELF\x02\x01"),
        "not a 64-bit little-endian ELF file"
    );
    let u16_at = |o: usize| u16::from_le_bytes([elf[o], elf[o + 1]]) as usize;
    let u32_at = |o: usize| u32::from_le_bytes(elf[o..o + 4].try_into().unwrap()) as usize;
    let u64_at = |o: usize| u64::from_le_bytes(elf[o..o + 8].try_into().unwrap()) as usize;
    let (shoff, shentsize, shnum, shstrndx) =
        (u64_at(0x28), u16_at(0x3a), u16_at(0x3c), u16_at(0x3e));
    let header = |i: usize| shoff + i * shentsize;
    let strtab = u64_at(header(shstrndx) + 0x18);
    (0..shnum)
        .map(|i| {
            let start = strtab + u32_at(header(i));
            let end = start + elf[start..].iter().position(|&b| b == 0).unwrap();
            String::from_utf8_lossy(&elf[start..end]).into_owned()
        })
        .collect()
}

fn read(path: PathBuf) -> String {
    std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn install_upgrade_uninstall_and_purge_into_a_destdir() {
    let dir = TestDir::new();
    let root = dir.join("root");
    let built = env!("CARGO_BIN_EXE_mgmot");
    let args = ["--prefix", "/opt/mgmot", "--binary", built, "--tract"];
    let said = install(&root, &args);

    let mut want = vec![
        "etc/mgmot/mgmot.example.toml",
        "etc/mgmot/mgmot.toml",
        "etc/systemd/system/mgmot.service",
        "opt/mgmot/bin/mgmot",
        "opt/mgmot/bin/mgmot.debug",
        "opt/mgmot/share/doc/mgmot/README.md",
        "opt/mgmot/share/mgmot/models/mgmot-det-fp32.onnx",
        "opt/mgmot/share/mgmot/models/mgmot-det-int8.onnx",
        "opt/mgmot/share/mgmot/models/mgmot-det-tiles-int8.onnx",
    ]
    .into_iter()
    .map(String::from)
    .collect::<Vec<_>>();
    // The documents the README links to, beside it.
    let docs = std::fs::read_dir(concat!(env!("CARGO_MANIFEST_DIR"), "/docs")).unwrap();
    let docs: Vec<String> = docs
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".md"))
        .map(|n| format!("opt/mgmot/share/doc/mgmot/docs/{n}"))
        .collect();
    assert!(docs.len() >= 5, "{docs:?}");
    want.extend(docs);
    want.sort();
    assert_eq!(files(&root), want, "{said}");

    // The binary: stripped, linked to its debug info, which holds the DWARF; it runs.
    let bin = root.join("opt/mgmot/bin/mgmot");
    let debug = root.join("opt/mgmot/bin/mgmot.debug");
    let (stripped, full) = (std::fs::read(&bin).unwrap(), std::fs::read(built).unwrap());
    let sections = elf_sections(&stripped);
    assert!(
        sections.iter().any(|s| s == ".gnu_debuglink"),
        "{sections:?}"
    );
    assert!(
        contains(&stripped, b"mgmot.debug\0"),
        "debuglink names no mgmot.debug"
    );
    // DWARF gone (.debug_gdb_scripts is not debug info: gdb's pretty-printer list, loaded).
    let dwarf = [".debug_info", ".debug_line", ".debug_str", ".debug_abbrev"];
    assert!(
        !sections.iter().any(|s| dwarf.contains(&s.as_str())),
        "{sections:?}"
    );
    assert!(elf_sections(&full).iter().any(|s| s == ".debug_info"));
    assert!(elf_sections(&std::fs::read(&debug).unwrap())
        .iter()
        .any(|s| s == ".debug_info"));
    eprintln!(
        "binary: {} bytes installed (stripped), {} bytes built, {} bytes of debug info",
        stripped.len(),
        full.len(),
        std::fs::metadata(&debug).unwrap().len()
    );
    assert!(stripped.len() < full.len() / 2, "{said}");
    let mode = |p: &Path| std::fs::metadata(p).unwrap().permissions().mode() & 0o777;
    assert_eq!(mode(&bin), 0o755);
    assert!(TestCommand::new(&bin)
        .arg("--version")
        .ok()
        .status
        .success());

    // The unit and the configuration point at this prefix; --tract: tract and the fp32 model.
    let unit = read(root.join("etc/systemd/system/mgmot.service"));
    assert!(
        unit.contains("\nExecStart=/opt/mgmot/bin/mgmot run --config /etc/mgmot/mgmot.toml\n"),
        "{unit}"
    );
    assert!(!unit.contains("/usr/local/"), "{unit}");
    let config_path = root.join("etc/mgmot/mgmot.toml");
    let config = read(config_path.clone());
    assert!(config.contains("\nbackend = \"tract\"\n"), "{config}");
    assert!(
        config.contains("\nmodel = \"/opt/mgmot/share/mgmot/models/mgmot-det-fp32.onnx\"\n"),
        "{config}"
    );
    assert!(!config.contains("\nort_library = "), "{config}");
    assert_eq!(mode(&config_path), 0o640, "the signing key is in it");
    // check-config requires the model to exist: the installed paths, under DESTDIR.
    let here = dir.write(
        "installed-here.toml",
        config.replace("\"/opt/mgmot/", &format!("\"{}/opt/mgmot/", root.display())),
    );
    let check = TestCommand::new(&bin).arg("check-config").arg(&here).ok();
    assert!(String::from_utf8_lossy(&check.stdout).contains(": ok"));

    // An upgrade keeps the configuration the user edited.
    std::fs::write(
        &config_path,
        config.replace("udpin:127.0.0.1:14551", "udpin:127.0.0.1:14561"),
    )
    .unwrap();
    let said = install(&root, &args);
    assert!(said.contains("keeping the existing"), "{said}");
    assert!(read(config_path.clone()).contains("udpin:127.0.0.1:14561"));

    // Uninstall: configuration and flight data stay.
    let state = root.join("var/lib/mgmot");
    std::fs::create_dir_all(&state).unwrap();
    std::fs::write(state.join("signing-state.json"), "{}").unwrap();
    install(&root, &["--uninstall", "--prefix", "/opt/mgmot"]);
    assert_eq!(
        files(&root),
        ["etc/mgmot/mgmot.toml", "var/lib/mgmot/signing-state.json"]
    );
    // Purge: nothing left.
    install(&root, &["--uninstall", "--purge", "--prefix", "/opt/mgmot"]);
    assert_eq!(files(&root), Vec::<String>::new());
    assert!(!root.join("etc/mgmot").exists() && !state.exists());
}

/// `--purge` alone, an unknown flag and a relative prefix are refused, naming the problem.
#[test]
fn install_refuses_bad_arguments() {
    let dir = TestDir::new();
    for (args, says) in [
        (&["--purge"][..], "--purge goes with --uninstall"),
        (&["--frobnicate"][..], "unknown argument --frobnicate"),
        (&["--prefix", "usr"][..], "absolute path"),
    ] {
        let out = TestCommand::new("bash")
            .arg(repo_file("scripts/install.sh"))
            .arg("--no-system")
            .args(args)
            .env("DESTDIR", dir.path())
            .output();
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {stderr}");
        assert!(stderr.contains(says), "{args:?}: {stderr}");
    }
    assert_eq!(files(dir.path()), Vec::<String>::new());
}

/// `mgmot detect` with `backend`, started with the kernel's memory-deny-write-execute
/// (`PR_SET_MDWE`, Linux 6.3+, what `MemoryDenyWriteExecute=yes` asks for: no mapping both
/// writable and executable, no mapping made executable later); its detections.
fn detect_under_mdwe(backend: &str, model: &str, ort: Option<&str>) -> String {
    let image = repo_file("tests/fixtures/detect/sim_heldout_a.jpg");
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_mgmot"));
    cmd.args(["detect", "--json", "--backend", backend, "--model"])
        .arg(repo_file(model))
        .arg(&image);
    if let Some(lib) = ort {
        cmd.arg("--ort-lib").arg(lib);
    }
    const PR_SET_MDWE: libc::c_int = 65;
    const PR_MDWE_REFUSE_EXEC_GAIN: libc::c_ulong = 1;
    // SAFETY: prctl is async-signal-safe; nothing else runs between fork and exec.
    unsafe {
        cmd.pre_exec(|| {
            if libc::prctl(PR_SET_MDWE, PR_MDWE_REFUSE_EXEC_GAIN, 0, 0, 0) != 0 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let out = cmd
        .output()
        .unwrap_or_else(|e| panic!("mgmot detect under PR_SET_MDWE (Linux 6.3+): {e}"));
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{backend}: {}: {}",
        out.status,
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

#[test]
fn the_detector_runs_under_memory_deny_write_execute() {
    let tract = detect_under_mdwe("tract", "models/mgmot-det-fp32.onnx", None);
    assert!(tract.contains("\"category_id\""), "tract: {tract}");
    let Some(lib) = std::env::var_os("ORT_DYLIB_PATH").filter(|p| Path::new(p).is_file()) else {
        missing_tool(
            "the_detector_runs_under_memory_deny_write_execute",
            "ORT_DYLIB_PATH (ONNX Runtime)",
        )
    };
    let lib = lib.to_string_lossy().into_owned();
    let ort = detect_under_mdwe("onnxruntime", "models/mgmot-det-int8.onnx", Some(&lib));
    assert!(ort.contains("\"category_id\""), "onnxruntime: {ort}");
}
