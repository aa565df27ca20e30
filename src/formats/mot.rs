//! MOTChallenge text files: ground truth (`gt.txt`) and tracker results (`<seq>.txt`).
//!
//! One object per line: `frame, id, x, y, w, h[, conf[, class[, visibility, ...]]]`,
//! comma separated (whitespace separated lines are accepted too). Boxes are
//! top-left corner and size in pixels; frames start at 1. Missing optional
//! columns default to `conf = 1` and `class = 1` (TrackEval's default for
//! tracker files); columns after the ninth (the world `x, y, z` of MOT15
//! results) are ignored. For ground truth `conf` is the "considered" flag (0 =
//! ignore this object); for results it is the detection confidence.
//!
//! # Folders of sequences
//!
//! [`discover_sequences`] pairs a ground-truth folder with a results folder.
//! The ground-truth folder may use either layout, even mixed:
//!
//! - MOTChallenge: `<gt>/<seq>/gt/gt.txt` (with an optional
//!   `<gt>/<seq>/seqinfo.ini` whose `seqLength` bounds the frame numbers, as in
//!   TrackEval); sub-folders without `gt/gt.txt` (e.g. `seqmaps`) are skipped;
//! - flat: `<gt>/<seq>.txt`.
//!
//! Results are always flat, `<pred>/<seq>.txt` (TrackEval's tracker layout).
//! A sequence without a results file is an error naming it, as in TrackEval;
//! results files without ground truth are ignored with a warning.

use std::fmt::Write as _;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::input::{self, InputKind};
use crate::eval::{Annotation, BoxXywh};
use crate::track::Appearance;

/// Errors from reading MOTChallenge files and folders.
#[derive(Debug, thiserror::Error)]
pub enum MotError {
    /// The file or folder could not be read.
    #[error("{}: {source}", path.display())]
    Io {
        /// What was being read.
        path: PathBuf,
        /// The underlying error.
        source: io::Error,
    },
    /// A line is malformed.
    #[error("{}:{line}: {problem}", path.display())]
    Parse {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// What is wrong with it.
        problem: String,
    },
    /// An id occurs twice in one frame.
    #[error("{}:{line}: id {id} occurs twice in frame {frame} (first on line {first_line})", path.display())]
    DuplicateId {
        /// The file.
        path: PathBuf,
        /// 1-based line of the second occurrence.
        line: usize,
        /// 1-based line of the first occurrence.
        first_line: usize,
        /// The frame.
        frame: u64,
        /// The repeated id.
        id: i64,
    },
    /// A frame number exceeds the sequence length given in `seqinfo.ini`.
    #[error("{}:{line}: frame {frame} is beyond the sequence length {seq_length} of {}", path.display(), seqinfo.display())]
    FrameBeyondSequence {
        /// The file.
        path: PathBuf,
        /// 1-based line number.
        line: usize,
        /// The frame.
        frame: u64,
        /// `seqLength` from the ini file.
        seq_length: u64,
        /// The ini file that set it.
        seqinfo: PathBuf,
    },
    /// A ground-truth sequence has no results file.
    #[error("sequence {sequence}: no results file {}", expected.display())]
    MissingPrediction {
        /// The sequence name.
        sequence: String,
        /// Where the results file was looked for.
        expected: PathBuf,
    },
    /// Two ground-truth files claim the same sequence name.
    #[error("sequence {sequence} is given twice: {} and {}", first.display(), second.display())]
    DuplicateSequence {
        /// The sequence name.
        sequence: String,
        /// One ground-truth file.
        first: PathBuf,
        /// The other one.
        second: PathBuf,
    },
    /// The ground-truth folder holds no sequence in either layout.
    #[error("{}: no sequences found (expected <seq>/gt/gt.txt or <seq>.txt)", path.display())]
    NoSequences {
        /// The folder.
        path: PathBuf,
    },
}

/// One line of a MOTChallenge file.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MotRecord {
    /// Frame number, from 1.
    pub frame: u64,
    /// Track id.
    pub id: i64,
    /// The box in pixels.
    pub bbox: BoxXywh,
    /// Ground truth: considered flag (0 = ignore); results: confidence.
    pub conf: f64,
    /// Class id (column 8), truncated to an integer as TrackEval does.
    pub class: i64,
    /// Visibility ratio (column 9) if given.
    pub visibility: Option<f64>,
    /// Detection files only: the box's colour signature, when column 11 holds one
    /// ([`Appearance::to_hex`]: `mgmot-sim detections --appearance`); any other column 11
    /// is ignored as before.
    pub appearance: Option<Appearance>,
}

impl MotRecord {
    /// This row as ground truth for [`crate::eval`]: considered iff `conf != 0`.
    pub fn to_gt_annotation(&self) -> Annotation {
        Annotation {
            frame: self.frame,
            id: self.id,
            bbox: self.bbox,
            class: self.class,
            considered: self.conf != 0.0,
        }
    }

    /// This row as a prediction for [`crate::eval`] (always kept).
    pub fn to_pred_annotation(&self) -> Annotation {
        Annotation {
            frame: self.frame,
            id: self.id,
            bbox: self.bbox,
            class: self.class,
            considered: true,
        }
    }
}

/// Parses the text of a MOTChallenge file; `path` only names it in errors.
pub fn parse_str(text: &str, path: &Path) -> Result<Vec<MotRecord>, MotError> {
    parse_records(text, path, true)
}

/// Reads a MOTChallenge detection file (`det.txt`: `frame,-1,x,y,w,h,score[,class]`), where
/// ids carry no meaning and may repeat within a frame.
pub fn read_detections(path: &Path) -> Result<Vec<MotRecord>, MotError> {
    let text = input::read_to_string(path, InputKind::MotText).map_err(|source| MotError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_records(&text, path, false)
}

/// Parses MOTChallenge lines; with `unique_ids`, a repeated (frame, id) pair is an error.
fn parse_records(text: &str, path: &Path, unique_ids: bool) -> Result<Vec<MotRecord>, MotError> {
    let mut records = Vec::new();
    let mut lines = Vec::new();
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    for (index, raw) in text.lines().enumerate() {
        let line = index + 1;
        let trimmed = raw.trim();
        if trimmed.is_empty() {
            continue;
        }
        let record = parse_line(trimmed).map_err(|problem| MotError::Parse {
            path: path.to_path_buf(),
            line,
            problem,
        })?;
        records.push(record);
        lines.push(line);
    }
    if unique_ids {
        check_unique_ids(&records, &lines, path)?;
    }
    Ok(records)
}

/// Rejects an id that occurs twice in a frame, naming the earliest line that
/// repeats one. Sorting is much cheaper than hashing for files of 10^5+ lines.
fn check_unique_ids(records: &[MotRecord], lines: &[usize], path: &Path) -> Result<(), MotError> {
    let mut keys: Vec<(u64, i64, usize)> = records
        .iter()
        .zip(lines)
        .map(|(r, &line)| (r.frame, r.id, line))
        .collect();
    keys.sort_unstable();
    let repeat = keys
        .windows(2)
        .filter(|w| w[0].0 == w[1].0 && w[0].1 == w[1].1)
        .min_by_key(|w| w[1].2);
    match repeat {
        None => Ok(()),
        Some(w) => {
            // The first line of this (frame, id) is the smallest one of its run.
            let first_line = keys
                .iter()
                .find(|k| k.0 == w[0].0 && k.1 == w[0].1)
                .map_or(w[0].2, |k| k.2);
            Err(MotError::DuplicateId {
                path: path.to_path_buf(),
                line: w[1].2,
                first_line,
                frame: w[0].0,
                id: w[0].1,
            })
        }
    }
}

/// Reads and parses one MOTChallenge file.
pub fn read_file(path: &Path) -> Result<Vec<MotRecord>, MotError> {
    let text = input::read_to_string(path, InputKind::MotText).map_err(|source| MotError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    parse_str(&text, path)
}

/// Writes records as `frame,id,x,y,w,h,conf,class,visibility` lines
/// (visibility `-1` when unknown), readable by [`parse_str`] and TrackEval.
pub fn write<W: Write>(mut out: W, records: &[MotRecord]) -> io::Result<()> {
    let mut line = String::new();
    for r in records {
        line.clear();
        let b = r.bbox;
        // Writing into a String cannot fail.
        let _ = writeln!(
            line,
            "{},{},{},{},{},{},{},{},{}",
            r.frame,
            r.id,
            b.x,
            b.y,
            b.w,
            b.h,
            r.conf,
            r.class,
            r.visibility.unwrap_or(-1.0)
        );
        out.write_all(line.as_bytes())?;
    }
    Ok(())
}

const COLUMN_NAMES: [&str; 9] = [
    "frame",
    "id",
    "x",
    "y",
    "width",
    "height",
    "conf",
    "class",
    "visibility",
];

/// Column (0-based) of a detection's colour signature.
const SIGNATURE_COLUMN: usize = 10;

fn parse_line(line: &str) -> Result<MotRecord, String> {
    let mut values = [0.0f64; 9];
    let mut count = 0;
    let mut appearance = None;
    let mut push = |field: &str| -> Result<(), String> {
        let field = field.trim();
        if count == SIGNATURE_COLUMN {
            appearance = Appearance::from_hex(field);
        }
        if count < values.len() {
            let name = COLUMN_NAMES[count];
            let v: f64 = field
                .parse()
                .map_err(|_| format!("column {} ({name}): {field:?} is not a number", count + 1))?;
            if !v.is_finite() {
                return Err(format!(
                    "column {} ({name}): {field:?} is not finite",
                    count + 1
                ));
            }
            values[count] = v;
        }
        count += 1;
        Ok(())
    };
    if line.contains(',') {
        // A trailing comma leaves an empty last field; TrackEval drops it too.
        let line = line.strip_suffix(',').unwrap_or(line);
        for f in line.split(',') {
            push(f)?;
        }
    } else {
        for f in line.split_whitespace() {
            push(f)?;
        }
    }
    if count < 6 {
        return Err(format!(
            "{count} columns, need at least 6 (frame, id, x, y, width, height)"
        ));
    }
    let frame = values[0];
    if frame.fract() != 0.0 || frame < 1.0 || frame > u32::MAX as f64 {
        return Err(format!("frame {frame} is not a whole number >= 1"));
    }
    let id = values[1];
    if id.fract() != 0.0 || id.abs() > i32::MAX as f64 {
        return Err(format!("id {id} is not a whole number"));
    }
    Ok(MotRecord {
        frame: frame as u64,
        id: id as i64,
        bbox: BoxXywh {
            x: values[2],
            y: values[3],
            w: values[4],
            h: values[5],
        },
        conf: if count > 6 { values[6] } else { 1.0 },
        // `as` truncates towards zero like numpy's astype(int); the value is
        // finite, so it cannot be NaN, and it saturates instead of wrapping.
        class: if count > 7 { values[7] as i64 } else { 1 },
        visibility: (count > 8).then_some(values[8]),
        appearance,
    })
}

/// One sequence of a folder evaluation.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceFiles {
    /// Sequence name (folder name or file stem).
    pub name: String,
    /// Ground-truth file.
    pub gt: PathBuf,
    /// Results file.
    pub pred: PathBuf,
    /// `seqLength` from `<seq>/seqinfo.ini`, when that file exists.
    pub seq_length: Option<SeqLength>,
}

/// A sequence length and the ini file it came from.
#[derive(Debug, Clone, PartialEq)]
pub struct SeqLength {
    /// Number of frames; valid frames are `1..=frames`.
    pub frames: u64,
    /// The `seqinfo.ini` it was read from.
    pub source: PathBuf,
}

impl SequenceFiles {
    /// Reads the ground truth and results of this sequence, checking frames
    /// against `seqLength` when known.
    pub fn read(&self) -> Result<(Vec<MotRecord>, Vec<MotRecord>), MotError> {
        let gt = read_file(&self.gt)?;
        let pred = read_file(&self.pred)?;
        if let Some(len) = &self.seq_length {
            check_frames(&self.gt, &gt, len)?;
            check_frames(&self.pred, &pred, len)?;
        }
        Ok((gt, pred))
    }
}

fn check_frames(path: &Path, records: &[MotRecord], len: &SeqLength) -> Result<(), MotError> {
    // Records keep no line numbers, so find the line again on the error path.
    match records.iter().position(|r| r.frame > len.frames) {
        None => Ok(()),
        Some(i) => {
            let line = input::read_to_string(path, InputKind::MotText)
                .ok()
                .and_then(|t| {
                    t.lines()
                        .enumerate()
                        .filter(|(_, l)| !l.trim().is_empty())
                        .nth(i)
                        .map(|(n, _)| n + 1)
                })
                .unwrap_or(0);
            Err(MotError::FrameBeyondSequence {
                path: path.to_path_buf(),
                line,
                frame: records[i].frame,
                seq_length: len.frames,
                seqinfo: len.source.clone(),
            })
        }
    }
}

fn io_err(path: &Path) -> impl FnOnce(io::Error) -> MotError + '_ {
    move |source| MotError::Io {
        path: path.to_path_buf(),
        source,
    }
}

/// Pairs every ground-truth sequence in `gt_dir` with `<pred_dir>/<seq>.txt`
/// (layouts in the module docs). Sequences come back sorted by name.
pub fn discover_sequences(gt_dir: &Path, pred_dir: &Path) -> Result<Vec<SequenceFiles>, MotError> {
    let mut found: Vec<(String, PathBuf, Option<SeqLength>)> = Vec::new();
    let entries = std::fs::read_dir(gt_dir).map_err(io_err(gt_dir))?;
    for entry in entries {
        let entry = entry.map_err(io_err(gt_dir))?;
        let path = entry.path();
        let Some(name) = path.file_name().and_then(|n| n.to_str()).map(str::to_owned) else {
            continue;
        };
        if path.is_dir() {
            let gt_file = path.join("gt").join("gt.txt");
            if gt_file.is_file() {
                let ini = path.join("seqinfo.ini");
                let seq_length = if ini.is_file() {
                    read_seq_length(&ini)?
                } else {
                    None
                };
                found.push((name, gt_file, seq_length));
            }
        } else if let Some(stem) = name.strip_suffix(".txt") {
            found.push((stem.to_owned(), path, None));
        }
    }
    found.sort_by(|a, b| a.0.cmp(&b.0));
    for pair in found.windows(2) {
        if pair[0].0 == pair[1].0 {
            return Err(MotError::DuplicateSequence {
                sequence: pair[0].0.clone(),
                first: pair[0].1.clone(),
                second: pair[1].1.clone(),
            });
        }
    }
    if found.is_empty() {
        return Err(MotError::NoSequences {
            path: gt_dir.to_path_buf(),
        });
    }
    let mut sequences = Vec::with_capacity(found.len());
    for (name, gt, seq_length) in found {
        let pred = pred_dir.join(format!("{name}.txt"));
        if !pred.is_file() {
            return Err(MotError::MissingPrediction {
                sequence: name,
                expected: pred,
            });
        }
        sequences.push(SequenceFiles {
            name,
            gt,
            pred,
            seq_length,
        });
    }
    warn_about_extra_results(pred_dir, &sequences);
    Ok(sequences)
}

fn warn_about_extra_results(pred_dir: &Path, sequences: &[SequenceFiles]) {
    let Ok(entries) = std::fs::read_dir(pred_dir) else {
        return;
    };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(stem) = name.to_str().and_then(|n| n.strip_suffix(".txt")) else {
            continue;
        };
        if !sequences.iter().any(|s| s.name == stem) {
            tracing::warn!(file = %entry.path().display(), "results file has no ground truth; ignored");
        }
    }
}

/// Reads `seqLength` from the `[Sequence]` section of a MOTChallenge
/// `seqinfo.ini`; `None` when the key is absent.
fn read_seq_length(ini: &Path) -> Result<Option<SeqLength>, MotError> {
    let text = input::read_to_string(ini, InputKind::Config).map_err(io_err(ini))?;
    for (index, line) in text.lines().enumerate() {
        let Some((key, value)) = line.split_once('=') else {
            continue;
        };
        if key.trim().eq_ignore_ascii_case("seqlength") {
            let frames = value.trim().parse::<u64>().map_err(|_| MotError::Parse {
                path: ini.to_path_buf(),
                line: index + 1,
                problem: format!("seqLength {:?} is not a whole number", value.trim()),
            })?;
            return Ok(Some(SeqLength {
                frames,
                source: ini.to_path_buf(),
            }));
        }
    }
    Ok(None)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<MotRecord>, MotError> {
        parse_str(text, Path::new("x.txt"))
    }

    #[test]
    fn parses_gt_and_result_lines() {
        let r =
            parse("1,2,10.5,20,30,40,1,3,0.5\n\n2, 3, 1, 2, 3, 4, 0.9, -1, -1, -1\n3 4 1 2 3 4\n")
                .unwrap();
        assert_eq!(r.len(), 3);
        assert_eq!((r[0].frame, r[0].id, r[0].class), (1, 2, 3));
        assert_eq!(
            r[0].bbox,
            BoxXywh {
                x: 10.5,
                y: 20.0,
                w: 30.0,
                h: 40.0
            }
        );
        assert_eq!(r[0].visibility, Some(0.5));
        assert_eq!((r[1].conf, r[1].class), (0.9, -1));
        assert_eq!(
            (r[2].frame, r[2].conf, r[2].class, r[2].visibility),
            (3, 1.0, 1, None)
        );
        assert!(r[0].to_gt_annotation().considered);
    }

    #[test]
    fn detection_lines_carry_a_signature_in_column_11() {
        let hex = "0f6944000000000031120000000000000000";
        let r = parse(&format!(
            "1,-1,491.46,404.88,11.99,14.97,0.5785,1,-1,-1,{hex}\n\
             2,-1,1,2,3,4,0.5,1,-1,-1\n\
             3,-1,1,2,3,4,0.5,1,-1,-1,7\n\
             4,-1,1,2,3,4,0.5,1,-1,-1,{}\n",
            "0".repeat(36)
        ))
        .unwrap();
        let a = r[0].appearance.expect("signature parsed");
        assert_eq!(a.to_hex().len(), hex.len());
        assert!(a.distance(&Appearance::from_hex(hex).unwrap()) < 1e-6);
        // No column 11, a number there, or an empty signature: none, and no error.
        assert!(r[1..].iter().all(|x| x.appearance.is_none()));
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let e = parse("1,1,0,0,1,1\n2,1,0,zero,1,1\n")
            .unwrap_err()
            .to_string();
        assert_eq!(e, "x.txt:2: column 4 (y): \"zero\" is not a number");
        let e = parse("1,1,0,0,1\n").unwrap_err().to_string();
        assert!(e.starts_with("x.txt:1: 5 columns"), "{e}");
        let e = parse("0,1,0,0,1,1\n").unwrap_err().to_string();
        assert!(e.contains("frame 0"), "{e}");
        let e = parse("1,1.5,0,0,1,1\n").unwrap_err().to_string();
        assert!(e.contains("id 1.5"), "{e}");
        let e = parse("1,1,nan,0,1,1\n").unwrap_err().to_string();
        assert!(e.contains("not finite"), "{e}");
        let e = parse("1,1,0,0,1,1\n1,1,5,5,1,1\n").unwrap_err().to_string();
        assert_eq!(e, "x.txt:2: id 1 occurs twice in frame 1 (first on line 1)");
    }

    #[test]
    fn write_then_parse_round_trips() {
        let records = parse("1,2,10.5,20,30,40,1,3,0.5\n2,3,1,2,3,4,0,1,-1\n").unwrap();
        let mut out = Vec::new();
        write(&mut out, &records).unwrap();
        let again = parse(std::str::from_utf8(&out).unwrap()).unwrap();
        assert_eq!(again[0], records[0]);
        assert_eq!(again[1].visibility, Some(-1.0));
    }

    proptest::proptest! {
        #[test]
        fn arbitrary_text_never_panics(text in "[0-9,. \\-a-z\\n]{0,200}") {
            let _ = parse(&text);
        }
    }
}
