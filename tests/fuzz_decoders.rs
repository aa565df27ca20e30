//! The fuzz targets on the stable toolchain, within the normal `cargo test`: every target
//! replays its committed corpus (`fuzz/corpus/<target>/`, seeds and regression inputs) and
//! then runs `MGMOT_FUZZ_CASES` inputs (default 2000) mutated from it or random, from a seeded
//! generator (`MGMOT_FUZZ_SEED`, default fixed, so a run is reproducible).
//!
//! The target bodies are `fuzz/targets/`, the ones cargo-fuzz runs (see `fuzz/README.md`).
//! A failing input is written to `<target tmp>/fuzz-findings/<target>/` and printed in hex.
//!
//! A long run: `MGMOT_FUZZ_CASES=1000000 cargo test --release --test main -- fuzz_decoders::
//! --nocapture`. `MGMOT_FUZZ_SUMMARY=FILE` appends each target's summary line to FILE.

#[path = "../fuzz/targets/mod.rs"]
mod targets;

use std::cell::RefCell;
use std::collections::BTreeMap;
use std::panic::{self, AssertUnwindSafe};
use std::path::{Path, PathBuf};
use std::sync::Once;
use std::time::{Duration, Instant};

/// SplitMix64: small, seedable, good enough to drive a mutator.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9e37_79b9_7f4a_7c15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
        z ^ (z >> 31)
    }

    /// Uniform in `0..n` (`n > 0`).
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }

    fn chance(&mut self, one_in: usize) -> bool {
        self.below(one_in) == 0
    }
}

fn env_u64(name: &str, default: u64) -> u64 {
    match std::env::var(name) {
        Ok(v) => {
            let v = v.trim();
            let parsed = match v.strip_prefix("0x") {
                Some(hex) => u64::from_str_radix(hex, 16),
                None => v.parse(),
            };
            parsed.unwrap_or_else(|_| panic!("{name}={v:?} is not a number"))
        }
        Err(_) => default,
    }
}

/// The committed corpus of a target, in name order.
fn corpus(name: &str) -> Vec<(PathBuf, Vec<u8>)> {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/corpus")
        .join(name);
    let mut files: Vec<PathBuf> = std::fs::read_dir(&dir)
        .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{}: no corpus", dir.display());
    files
        .into_iter()
        .map(|p| {
            let bytes = std::fs::read(&p).unwrap();
            (p, bytes)
        })
        .collect()
}

/// Numbers that break parsers, put in place of a number of a text input.
const NUMBER_TOKENS: &[&str] = &[
    "0",
    "-0",
    "-1",
    "0.5",
    "nan",
    "NaN",
    "inf",
    "-inf",
    "1e308",
    "-1e308",
    "1.7976931348623157e308",
    "-1.7976931348623157e308",
    "1e309",
    "1e-300",
    "1e-320",
    "4e-324",
    "255",
    "256",
    "65535",
    "65536",
    "2147483647",
    "2147483648",
    "-2147483649",
    "4294967295",
    "4294967296",
    "9223372036854775807",
    "9223372036854775808",
    "-9223372036854775809",
    "18446744073709551615",
    "18446744073709551616",
    "1e19",
    "1e20",
];

/// The tokens of `fuzz/dict/<name>.dict` (libFuzzer's format: one `"..."` a line, with `\\`,
/// `\"` and `\xNN` escapes; `#` comments).
fn dictionary(name: &str) -> Vec<Vec<u8>> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("fuzz/dict")
        .join(format!("{name}.dict"));
    let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut tokens = Vec::new();
    for line in text.lines() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let quoted = &line[line.find('"').expect("a quoted token")..];
        let body = quoted
            .strip_prefix('"')
            .and_then(|q| q.strip_suffix('"'))
            .unwrap_or_else(|| panic!("{}: bad line {line}", path.display()));
        let mut token = Vec::new();
        let mut bytes = body.bytes();
        while let Some(b) = bytes.next() {
            if b != b'\\' {
                token.push(b);
                continue;
            }
            match bytes.next() {
                Some(b'x') => {
                    let hex = [bytes.next().unwrap(), bytes.next().unwrap()];
                    let hex = std::str::from_utf8(&hex).unwrap();
                    token.push(u8::from_str_radix(hex, 16).unwrap());
                }
                Some(c) => token.push(c),
                None => panic!("{}: bad escape in {line}", path.display()),
            }
        }
        tokens.push(token);
    }
    tokens
}

const INTERESTING_U8: [u8; 8] = [0, 1, 0x7f, 0x80, 0xff, b'0', b'9', b'-'];
const INTERESTING_U32: [u32; 9] = [
    0,
    1,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    0x7fc0_0000, // f32 NaN
    0x7f80_0000, // f32 +inf
    0xff80_0000, // f32 -inf
    0x0000_ffff,
];

/// One of libFuzzer's basic mutations, or a dictionary token, applied to `data`.
fn mutate_once(data: &mut Vec<u8>, rng: &mut Rng, other: &[u8], dictionary: &[Vec<u8>]) {
    let len = data.len();
    match rng.below(12) {
        0 if len > 0 => {
            let i = rng.below(len);
            data[i] ^= 1 << rng.below(8);
        }
        1 if len > 0 => {
            let i = rng.below(len);
            data[i] = rng.next() as u8;
        }
        2 if len > 0 => {
            let i = rng.below(len);
            data[i] = INTERESTING_U8[rng.below(INTERESTING_U8.len())];
        }
        3 if len >= 4 => {
            let i = rng.below(len - 3);
            let v = INTERESTING_U32[rng.below(INTERESTING_U32.len())];
            data[i..i + 4].copy_from_slice(&v.to_le_bytes());
        }
        4 if len > 0 => {
            // Delete a range.
            let i = rng.below(len);
            let n = 1 + rng.below((len - i).min(16));
            data.drain(i..i + n);
        }
        5 => {
            // Insert random bytes.
            let i = rng.below(len + 1);
            let n = 1 + rng.below(8);
            let bytes: Vec<u8> = (0..n).map(|_| rng.next() as u8).collect();
            data.splice(i..i, bytes);
        }
        6 if len > 0 => {
            // Duplicate a range.
            let i = rng.below(len);
            let n = 1 + rng.below((len - i).min(64));
            let chunk = data[i..i + n].to_vec();
            let at = rng.below(len + 1);
            data.splice(at..at, chunk);
        }
        7 if !other.is_empty() => {
            // Splice in a range of another corpus entry.
            let i = rng.below(other.len());
            let n = 1 + rng.below((other.len() - i).min(256));
            let at = rng.below(len + 1);
            let end = (at + rng.below(n + 1)).min(len);
            data.splice(at..end, other[i..i + n].iter().copied());
        }
        8 | 9 if !dictionary.is_empty() => {
            let token = &dictionary[rng.below(dictionary.len())];
            let at = rng.below(len + 1);
            if rng.chance(2) {
                data.splice(at..at, token.iter().copied());
            } else {
                let end = (at + token.len()).min(len);
                data.splice(at..end, token.iter().copied());
            }
        }
        10 if len > 0 => data.truncate(rng.below(len)),
        _ => {
            // Replace a run of digits (a number in a text format) with a tricky one.
            let starts: Vec<usize> = (0..len)
                .filter(|&i| data[i].is_ascii_digit() && (i == 0 || !data[i - 1].is_ascii_digit()))
                .collect();
            if starts.is_empty() {
                return;
            }
            let i = starts[rng.below(starts.len())];
            let mut end = i;
            while end < len && (data[end].is_ascii_digit() || b".eE+-".contains(&data[end])) {
                end += 1;
            }
            let n = NUMBER_TOKENS[rng.below(NUMBER_TOKENS.len())];
            data.splice(i..end, n.bytes());
        }
    }
}

/// The next generated input: mostly a corpus entry mutated a few times, sometimes random
/// bytes.
fn generate(rng: &mut Rng, corpus: &[(PathBuf, Vec<u8>)], dictionary: &[Vec<u8>]) -> Vec<u8> {
    if rng.chance(16) {
        let n = rng.below(512);
        return (0..n).map(|_| rng.next() as u8).collect();
    }
    let mut data = corpus[rng.below(corpus.len())].1.clone();
    let other = &corpus[rng.below(corpus.len())].1;
    for _ in 0..1 + rng.below(8) {
        mutate_once(&mut data, rng, other, dictionary);
    }
    data
}

thread_local! {
    /// Set while a target runs on this thread: its panic is recorded here, not printed.
    static CAUGHT: RefCell<Option<Option<String>>> = const { RefCell::new(None) };
}

/// Installs (once) a panic hook that records the panics of target runs and leaves every
/// other panic to the default hook.
fn install_hook() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        let default = panic::take_hook();
        panic::set_hook(Box::new(move |info| {
            let recorded = CAUGHT.with(|c| {
                let mut c = c.borrow_mut();
                match c.as_mut() {
                    Some(slot) => {
                        let message = info
                            .payload()
                            .downcast_ref::<&str>()
                            .map(|s| s.to_string())
                            .or_else(|| info.payload().downcast_ref::<String>().cloned())
                            .unwrap_or_default();
                        let at = info
                            .location()
                            .map(|l| format!("{}:{}", l.file(), l.line()))
                            .unwrap_or_default();
                        *slot = Some(format!("at {at}: {message}"));
                        true
                    }
                    None => false,
                }
            });
            if !recorded {
                default(info);
            }
        }));
    });
}

/// Runs the target on one input: `Err(panic message)` if it panicked.
fn run_one(target: fn(&[u8]), data: &[u8]) -> Result<(), String> {
    CAUGHT.with(|c| *c.borrow_mut() = Some(None));
    let result = panic::catch_unwind(AssertUnwindSafe(|| target(data)));
    let message = CAUGHT.with(|c| c.borrow_mut().take()).flatten();
    result.map_err(|_| message.unwrap_or_else(|| "panic".into()))
}

fn hex(data: &[u8]) -> String {
    data.iter().map(|b| format!("{b:02x}")).collect()
}

/// FNV-1a, to name finding files.
fn fnv(data: &[u8]) -> u64 {
    data.iter().fold(0xcbf2_9ce4_8422_2325, |h, &b| {
        (h ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3)
    })
}

/// Replays the corpus of `name`, then runs the generated inputs; fails listing every distinct
/// panic (by message) with its smallest input.
fn fuzz(name: &str) {
    install_hook();
    let &(_, target) = targets::ALL
        .iter()
        .find(|(n, _)| *n == name)
        .unwrap_or_else(|| panic!("no target {name}"));
    let corpus = corpus(name);
    let dictionary = dictionary(name);
    let cases = env_u64("MGMOT_FUZZ_CASES", 2000);
    let seed = env_u64("MGMOT_FUZZ_SEED", 0x6d67_6d6f_7466_757a) ^ fnv(name.as_bytes());
    let mut findings: BTreeMap<String, (String, Vec<u8>)> = BTreeMap::new();
    let mut record = |origin: String, message: String, data: Vec<u8>| {
        // Messages carry values: the panic's location tells findings apart.
        let key = message.split(": ").next().unwrap_or_default().to_owned();
        let smaller = findings
            .get(&key)
            .is_none_or(|(_, old)| data.len() < old.len());
        if smaller {
            findings.insert(key, (format!("{origin}: {message}"), data));
        }
    };
    let start = Instant::now();
    let mut slowest = (Duration::ZERO, Vec::new());
    let mut timed = |data: &[u8]| {
        let t = Instant::now();
        let r = run_one(target, data);
        let dt = t.elapsed();
        if dt > slowest.0 {
            slowest = (dt, data.to_vec());
        }
        r
    };
    for (path, data) in &corpus {
        if let Err(m) = timed(data) {
            record(path.display().to_string(), m, data.clone());
        }
    }
    let mut rng = Rng(seed);
    for k in 0..cases {
        let data = generate(&mut rng, &corpus, &dictionary);
        if let Err(m) = timed(&data) {
            record(format!("generated input {k} (seed {seed:#x})"), m, data);
        }
    }
    let elapsed = start.elapsed();
    let summary = format!(
        "fuzz {name}: {} corpus inputs + {cases} generated (seed {seed:#x}) in {:.1} s, \
         slowest input {:.1} ms ({} bytes), {} finding(s)",
        corpus.len(),
        elapsed.as_secs_f64(),
        slowest.0.as_secs_f64() * 1e3,
        slowest.1.len(),
        findings.len()
    );
    println!("{summary}");
    // `MGMOT_FUZZ_SUMMARY=FILE`: the line is also appended there, for a caller (scripts/
    // test.sh) that runs the fuzz targets inside the whole suite, where output is captured.
    if let Some(path) = std::env::var_os("MGMOT_FUZZ_SUMMARY") {
        use std::io::Write;
        let mut f = std::fs::OpenOptions::new()
            .create(true)
            .append(true)
            .open(&path)
            .unwrap_or_else(|e| panic!("MGMOT_FUZZ_SUMMARY {}: {e}", Path::new(&path).display()));
        writeln!(f, "{summary}").unwrap();
    }
    if findings.is_empty() {
        return;
    }
    let out = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join("fuzz-findings")
        .join(name);
    std::fs::create_dir_all(&out).unwrap();
    let mut report = String::new();
    for (what, data) in findings.values() {
        let file = out.join(format!("{:016x}", fnv(data)));
        std::fs::write(&file, data).unwrap();
        let shown = &data[..data.len().min(512)];
        report.push_str(&format!(
            "\n- {what}\n  input ({} bytes, saved as {}): {}{}\n",
            data.len(),
            file.display(),
            hex(shown),
            if shown.len() < data.len() { "..." } else { "" }
        ));
    }
    panic!("fuzz target {name}: {} finding(s):{report}", findings.len());
}

#[test]
fn mavlink_frames() {
    fuzz("mavlink_frames");
}

#[test]
fn mavlink_messages() {
    fuzz("mavlink_messages");
}

#[test]
fn sim_framing() {
    fuzz("sim_framing");
}

#[test]
fn seadronessee_json() {
    fuzz("seadronessee_json");
}

#[test]
fn mot_txt() {
    fuzz("mot_txt");
}

#[test]
fn runtime_config() {
    fuzz("runtime_config");
}

/// Every target has a test above, and every corpus folder a target.
#[test]
fn every_target_is_run() {
    let this = include_str!("fuzz_decoders.rs");
    for (name, _) in targets::ALL {
        assert!(
            this.contains(&format!("fuzz(\"{name}\");")),
            "{name} has no test"
        );
        assert!(!dictionary(name).is_empty(), "{name}: empty dictionary");
    }
    let fuzz_dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz");
    let manifest = std::fs::read_to_string(fuzz_dir.join("Cargo.toml")).unwrap();
    for (name, _) in targets::ALL {
        assert!(
            manifest.contains(&format!("name = \"{name}\"")),
            "{name} is no cargo-fuzz binary"
        );
    }
    for entry in std::fs::read_dir(fuzz_dir.join("corpus")).unwrap() {
        let name = entry.unwrap().file_name();
        let name = name.to_string_lossy();
        assert!(
            targets::ALL.iter().any(|(n, _)| *n == name),
            "fuzz/corpus/{name} belongs to no target"
        );
    }
}
