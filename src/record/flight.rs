//! A flight's folder: `<root>/<UTC start>-sys<id>/` with `flight.json`, `config.toml`,
//! `frames.ndjson`, `flight.tlog` and `keyframes/`. Creating one, keeping the root under its
//! size cap, and reading one back (tolerating a record cut short by a crash).

use super::format::{EndRecord, FlightInfo, FrameRecord, GapRecord, Record, FORMAT, VERSION};
use super::tlog::{self, TlogEntry};
use super::RecordError;
use sha2::{Digest, Sha256};
use std::fs::File;
use std::io::{BufRead, BufReader, BufWriter, Read};
use std::path::{Path, PathBuf};

/// `flight.json`.
pub const INFO: &str = "flight.json";
/// `config.toml`: the effective configuration.
pub const CONFIG: &str = "config.toml";
/// `frames.ndjson`: the per-frame record.
pub const FRAMES: &str = "frames.ndjson";
/// `flight.tlog`: every MAVLink packet in and out.
pub const TLOG: &str = "flight.tlog";
/// `keyframes/`: downscaled JPEGs.
pub const KEYFRAMES: &str = "keyframes";

/// The open files of a flight being recorded, and the lengths of their whole records.
pub(super) struct FlightFiles {
    pub dir: PathBuf,
    pub frames: File,
    pub frames_len: u64,
    pub tlog: BufWriter<File>,
    /// Bytes of whole entries known to be in the file.
    pub tlog_len: u64,
    /// Bytes of whole entries written into the buffer (in the file after a flush).
    pub tlog_len_buffered: u64,
}

/// Opens `path` for appending.
fn append(path: &Path) -> std::io::Result<File> {
    std::fs::OpenOptions::new()
        .create(true)
        .append(true)
        .open(path)
}

fn io_err(path: &Path) -> impl FnOnce(std::io::Error) -> RecordError + '_ {
    move |source| RecordError::Io {
        path: path.to_owned(),
        source,
    }
}

/// The folder name of a flight: its UTC start (`20261201T213821Z`) and the vehicle's
/// system id.
pub fn folder_name(started_unix_us: u64, system_id: u8) -> String {
    let secs = i64::try_from(started_unix_us / 1_000_000).unwrap_or(0);
    let t = chrono::DateTime::from_timestamp(secs, 0).unwrap_or_default();
    format!("{}-sys{system_id}", t.format("%Y%m%dT%H%M%SZ"))
}

/// Creates a flight's folder under `root` (made if missing) with its `flight.json` and
/// `config.toml`, and opens the record files.
pub(super) fn create(
    root: &Path,
    info: &FlightInfo,
    config_toml: &str,
) -> Result<FlightFiles, RecordError> {
    create_avoiding(root, info, config_toml, &[])
}

/// [`create`], never with one of the names in `avoid` (folders of this flight that were
/// deleted: a fresh folder must not look like the deleted one recreated).
pub(super) fn create_avoiding(
    root: &Path,
    info: &FlightInfo,
    config_toml: &str,
    avoid: &[PathBuf],
) -> Result<FlightFiles, RecordError> {
    std::fs::create_dir_all(root).map_err(io_err(root))?;
    let base = folder_name(info.started_unix_us, info.system_id);
    let mut dir = root.join(&base);
    let mut n = 1;
    // Two runs in one second (a restart): the second gets a suffix.
    loop {
        if avoid.contains(&dir) && n < 100 {
            n += 1;
            dir = root.join(format!("{base}-{n}"));
            continue;
        }
        match std::fs::create_dir(&dir) {
            Ok(()) => break,
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists && n < 100 => {
                n += 1;
                dir = root.join(format!("{base}-{n}"));
            }
            Err(e) => return Err(io_err(&dir)(e)),
        }
    }
    let info_text = serde_json::to_string_pretty(info).map_err(|e| RecordError::Io {
        path: dir.join(INFO),
        source: std::io::Error::other(e),
    })? + "\n";
    let info_path = dir.join(INFO);
    std::fs::write(&info_path, info_text).map_err(io_err(&info_path))?;
    let config_path = dir.join(CONFIG);
    std::fs::write(&config_path, config_toml).map_err(io_err(&config_path))?;
    let frames_path = dir.join(FRAMES);
    let frames = append(&frames_path).map_err(io_err(&frames_path))?;
    let tlog_path = dir.join(TLOG);
    let tlog = append(&tlog_path).map_err(io_err(&tlog_path))?;
    Ok(FlightFiles {
        dir,
        frames,
        frames_len: 0,
        tlog: BufWriter::with_capacity(64 * 1024, tlog),
        tlog_len: 0,
        tlog_len_buffered: 0,
    })
}

/// Bytes under `dir` (files only, not following links).
fn size_of(dir: &Path) -> u64 {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return 0;
    };
    entries
        .flatten()
        .map(|e| match e.file_type() {
            Ok(t) if t.is_dir() => size_of(&e.path()),
            Ok(t) if t.is_file() => e.metadata().map_or(0, |m| m.len()),
            _ => 0,
        })
        .sum()
}

/// The flights under `root` (folders holding a `flight.json`), oldest first by name (the
/// name starts with the UTC start).
pub fn list(root: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(root) else {
        return Vec::new();
    };
    let mut flights: Vec<PathBuf> = entries
        .flatten()
        .map(|e| e.path())
        .filter(|p| p.join(INFO).is_file())
        .collect();
    flights.sort();
    flights
}

/// Deletes the oldest flights under `root` other than `current` until all of them and
/// `current_bytes` fit in `cap`; returns the deleted folders.
pub(super) fn enforce_cap(
    root: &Path,
    current: &Path,
    current_bytes: u64,
    cap: u64,
) -> std::io::Result<Vec<PathBuf>> {
    let others: Vec<(PathBuf, u64)> = list(root)
        .into_iter()
        .filter(|p| p != current)
        .map(|p| {
            let s = size_of(&p);
            (p, s)
        })
        .collect();
    let mut total: u64 = current_bytes + others.iter().map(|(_, s)| s).sum::<u64>();
    let mut deleted = Vec::new();
    for (p, s) in others {
        if total <= cap {
            break;
        }
        std::fs::remove_dir_all(&p)?;
        total -= s;
        deleted.push(p);
    }
    Ok(deleted)
}

/// SHA-256 of a file (lowercase hex) and its size.
pub fn sha256_of(path: &Path) -> std::io::Result<(String, u64)> {
    let mut file = File::open(path)?;
    let mut hasher = Sha256::new();
    let mut buf = vec![0u8; 1 << 16];
    let mut bytes = 0u64;
    loop {
        let n = file.read(&mut buf)?;
        if n == 0 {
            break;
        }
        hasher.update(&buf[..n]);
        bytes += n as u64;
    }
    let hex = hasher
        .finalize()
        .iter()
        .map(|b| format!("{b:02x}"))
        .collect::<String>();
    Ok((hex, bytes))
}

/// A recorded flight, read back.
#[derive(Debug, Clone)]
pub struct Flight {
    /// Its folder.
    pub dir: PathBuf,
    /// `flight.json`.
    pub info: FlightInfo,
    /// `config.toml`'s text.
    pub config_toml: String,
    /// The frame records, in order.
    pub frames: Vec<FrameRecord>,
    /// Where recording stopped and resumed.
    pub gaps: Vec<GapRecord>,
    /// The end record (`None`: the run did not end cleanly, e.g. a crash or power loss).
    pub end: Option<EndRecord>,
    /// Lines that could not be read (a line cut short by a crash is the usual one).
    pub bad_lines: Vec<usize>,
}

impl Flight {
    /// Reads a flight's folder. A missing or foreign `flight.json` is an error; lines of
    /// `frames.ndjson` that do not parse (a crash cuts the last one short) are skipped and
    /// listed in `bad_lines`.
    pub fn load(dir: &Path) -> Result<Self, RecordError> {
        let info_path = dir.join(INFO);
        let text = std::fs::read_to_string(&info_path).map_err(io_err(&info_path))?;
        let info: FlightInfo = serde_json::from_str(&text).map_err(|e| RecordError::Format {
            path: info_path.clone(),
            message: e.to_string(),
        })?;
        if info.format != FORMAT || info.version > VERSION {
            return Err(RecordError::Format {
                path: info_path,
                message: format!(
                    "format {:?} version {} (this mgmot reads {FORMAT:?} up to version {VERSION})",
                    info.format, info.version
                ),
            });
        }
        let config_path = dir.join(CONFIG);
        let config_toml = std::fs::read_to_string(&config_path).map_err(io_err(&config_path))?;
        let frames_path = dir.join(FRAMES);
        let file = File::open(&frames_path).map_err(io_err(&frames_path))?;
        let mut flight = Flight {
            dir: dir.to_owned(),
            info,
            config_toml,
            frames: Vec::new(),
            gaps: Vec::new(),
            end: None,
            bad_lines: Vec::new(),
        };
        for (n, line) in BufReader::new(file).split(b'\n').enumerate() {
            let line = line.map_err(io_err(&frames_path))?;
            if line.is_empty() {
                continue;
            }
            match serde_json::from_slice::<Record>(&line) {
                Ok(Record::Frame(f)) => flight.frames.push(*f),
                Ok(Record::Gap(g)) => flight.gaps.push(g),
                Ok(Record::End(e)) => flight.end = Some(e),
                Err(_) => flight.bad_lines.push(n + 1),
            }
        }
        Ok(flight)
    }

    /// `flight.tlog`'s packets, and whether it ended cleanly (a crash can cut the last one).
    pub fn tlog(&self) -> Result<(Vec<TlogEntry>, bool), RecordError> {
        let path = self.dir.join(TLOG);
        let bytes = std::fs::read(&path).map_err(io_err(&path))?;
        Ok(tlog::parse(&bytes))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::record::format::{DetectorIdentity, EndRecord};

    fn info(started_unix_us: u64) -> FlightInfo {
        FlightInfo {
            format: FORMAT.into(),
            version: VERSION,
            mgmot_version: "test".into(),
            started_utc: String::new(),
            started_unix_us,
            system_id: 7,
            component_id: 191,
            detector: DetectorIdentity {
                kind: "onnx".into(),
                file: "m.onnx".into(),
                sha256: String::new(),
                bytes: 0,
            },
            tile_detector: None,
            config_file: CONFIG.into(),
        }
    }

    #[test]
    fn folders_are_named_by_utc_start_and_system_id_and_never_reused() {
        // 2026-12-01T21:38:21Z
        let t = 1_796_161_101_000_000;
        assert_eq!(folder_name(t, 7), "20261201T213821Z-sys7");
        let root = tempfile::tempdir().unwrap();
        let a = create(root.path(), &info(t), "").unwrap();
        let b = create(root.path(), &info(t), "").unwrap();
        assert_ne!(a.dir, b.dir);
        assert!(b.dir.ends_with("20261201T213821Z-sys7-2"));
        assert_eq!(list(root.path()), vec![a.dir, b.dir]);
    }

    #[test]
    fn the_cap_deletes_the_oldest_other_flights_first() {
        let root = tempfile::tempdir().unwrap();
        let dirs: Vec<PathBuf> = (0..3)
            .map(|i| {
                let f = create(root.path(), &info(1_000_000_000 + i * 1_000_000), "").unwrap();
                std::fs::write(f.dir.join(TLOG), vec![0u8; 10_000]).unwrap();
                f.dir
            })
            .collect();
        let current = &dirs[2];
        // Room for the current flight and one more: the oldest goes.
        let deleted = enforce_cap(root.path(), current, 10_000, 25_000).unwrap();
        assert_eq!(deleted, vec![dirs[0].clone()]);
        assert!(!dirs[0].exists() && dirs[1].exists() && current.exists());
        // The current flight is never deleted, even when it alone is over the cap.
        let deleted = enforce_cap(root.path(), current, 50_000, 25_000).unwrap();
        assert_eq!(deleted, vec![dirs[1].clone()]);
        assert!(current.exists());
    }

    #[test]
    fn a_flight_reads_back_skipping_a_cut_line_and_refuses_a_foreign_folder() {
        let root = tempfile::tempdir().unwrap();
        let f = create(root.path(), &info(1), "[mavlink]\n").unwrap();
        let end = Record::End(EndRecord {
            unix_us: 5,
            frames_written: 0,
            frames_dropped_queue: 0,
            packets_dropped_queue: 0,
            frames_lost_stopped: 0,
            keyframes: 0,
            run_stats: None,
        });
        let mut text = serde_json::to_string(&end).unwrap();
        text.push('\n');
        text.push_str("{\"type\":\"frame\",\"frame\":1,\"ti");
        std::fs::write(f.dir.join(FRAMES), text).unwrap();
        let flight = Flight::load(&f.dir).unwrap();
        assert_eq!(flight.bad_lines, vec![2]);
        assert!(flight.end.is_some() && flight.frames.is_empty());
        assert_eq!(flight.config_toml, "[mavlink]\n");
        assert!(Flight::load(root.path()).is_err());
        let mut other = info(1);
        other.format = "something-else".into();
        std::fs::write(f.dir.join(INFO), serde_json::to_string(&other).unwrap()).unwrap();
        let e = Flight::load(&f.dir).unwrap_err().to_string();
        assert!(e.contains("something-else"), "{e}");
    }
}
