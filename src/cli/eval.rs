//! `mgmot eval`: HOTA, CLEAR and Identity metrics of tracking results against
//! ground truth, computed as TrackEval does (see `mgmot::eval`).

use std::collections::BTreeMap;
use std::io::{self, Write};
use std::path::{Path, PathBuf};

use super::stdout::Stdout;
use anyhow::{bail, Context};
use mgmot::eval::{
    combine_classes_class_averaged, combine_sequences, evaluate_sequence, Annotation,
    ClassSelection, PreparedSequence, SequenceResult, Summary,
};
use mgmot::formats::mot::{self, MotRecord};
use serde::Serialize;

/// What `mgmot eval --help` says about inputs and output, beyond the flags.
const AFTER_HELP: &str = "\
Metrics are computed exactly as TrackEval computes them.

PATH is one MOTChallenge txt file on each side, or a folder on each side. A
ground-truth folder holds sequences as <seq>/gt/gt.txt (MOTChallenge layout,
with an optional <seq>/seqinfo.ini whose seqLength bounds the frames) or as
<seq>.txt; the results folder holds <seq>.txt for every ground-truth sequence
(a missing one is an error; extra ones are ignored with a warning).

Evaluation is class-agnostic: ground-truth rows with conf 0 are ignored and
every result row is kept. --per-class evaluates each class (column 8) alone.

JSON (--json): for two files, one object with the keys HOTA, DetA, AssA,
DetRe, DetPr, AssRe, AssPr, LocA, MOTA, MOTP, IDF1, IDR, IDP, IDSW, Frag, MT,
PT, ML, FP, FN, Recall, Precision (ratios as fractions, counts as integers).
For folders: {\"sequences\": {\"<seq>\": {...}}, \"combined\": {...}}.
With --per-class: {\"classes\": {\"<class>\": <one of the above>},
\"class_averaged\": {...}, \"detection_averaged\": {...}}, classes combined as
TrackEval's class-averaged and detection-averaged results.";

/// Arguments of `mgmot eval` (inputs and output are described in [`AFTER_HELP`]).
#[derive(Debug, clap::Args)]
#[command(after_long_help = AFTER_HELP)]
pub struct Args {
    /// Ground truth: a MOTChallenge txt file or a folder of sequences.
    #[arg(long, value_name = "PATH")]
    gt: PathBuf,
    /// Tracking results: a MOTChallenge txt file or a folder of `<seq>.txt`.
    #[arg(long, value_name = "PATH")]
    pred: PathBuf,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
    /// Evaluate every class (column 8) separately instead of class-agnostic.
    #[arg(long)]
    per_class: bool,
}

/// Runs `mgmot eval`.
pub fn run(args: Args) -> anyhow::Result<()> {
    let (sequences, is_folder) = load(&args.gt, &args.pred)?;
    let output = if args.per_class {
        evaluate_per_class(&sequences, is_folder)?
    } else {
        Output::Single(evaluate_all(&sequences, ClassSelection::All, is_folder)?)
    };
    let mut stdout = Stdout::lock();
    if args.json {
        writeln!(stdout, "{}", serde_json::to_string_pretty(&output)?)?;
    } else {
        print_tables(&mut stdout, &output)?;
    }
    Ok(())
}

/// Ground truth and results of one sequence, as annotations.
struct LoadedSequence {
    name: String,
    gt: Vec<Annotation>,
    pred: Vec<Annotation>,
}

fn load(gt: &Path, pred: &Path) -> anyhow::Result<(Vec<LoadedSequence>, bool)> {
    let (gt_dir, pred_dir) = (gt.is_dir(), pred.is_dir());
    if gt_dir != pred_dir {
        bail!(
            "--gt {} and --pred {} must both be files or both be folders",
            gt.display(),
            pred.display()
        );
    }
    if !gt_dir {
        let name = gt
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned())
            .unwrap_or_else(|| "sequence".to_owned());
        let (g, p) = read_pair(gt, pred)?;
        return Ok((vec![to_loaded(name, &g, &p)], false));
    }
    let files = mot::discover_sequences(gt, pred)?;
    let mut sequences = Vec::with_capacity(files.len());
    for f in &files {
        let (g, p) = f.read()?;
        sequences.push(to_loaded(f.name.clone(), &g, &p));
    }
    Ok((sequences, true))
}

/// Reads both files, the results on a second thread.
fn read_pair(gt: &Path, pred: &Path) -> anyhow::Result<(Vec<MotRecord>, Vec<MotRecord>)> {
    std::thread::scope(|scope| {
        let pred_job = scope.spawn(|| mot::read_file(pred));
        let g = mot::read_file(gt)?;
        let p = match pred_job.join() {
            Ok(result) => result?,
            Err(_) => bail!("reading {} failed", pred.display()),
        };
        Ok((g, p))
    })
}

fn to_loaded(name: String, gt: &[MotRecord], pred: &[MotRecord]) -> LoadedSequence {
    LoadedSequence {
        name,
        gt: gt.iter().map(MotRecord::to_gt_annotation).collect(),
        pred: pred.iter().map(MotRecord::to_pred_annotation).collect(),
    }
}

/// Results of one class (or of all objects).
#[derive(Serialize)]
#[serde(untagged)]
enum Evaluation {
    /// Two files: just the metrics.
    File(Summary),
    /// Two folders: per sequence and combined.
    Folder {
        sequences: BTreeMap<String, Summary>,
        combined: Summary,
    },
}

#[derive(Serialize)]
#[serde(untagged)]
enum Output {
    Single(Evaluation),
    PerClass {
        classes: BTreeMap<i64, Evaluation>,
        class_averaged: Option<Summary>,
        detection_averaged: Option<Summary>,
    },
}

fn evaluate_class(
    sequences: &[LoadedSequence],
    classes: ClassSelection,
) -> anyhow::Result<Vec<SequenceResult>> {
    sequences
        .iter()
        .map(|s| {
            let prepared = PreparedSequence::new(&s.gt, &s.pred, classes)
                .with_context(|| format!("sequence {}", s.name))?;
            Ok(evaluate_sequence(&prepared))
        })
        .collect()
}

fn evaluation_of(
    sequences: &[LoadedSequence],
    results: &[SequenceResult],
    is_folder: bool,
) -> Evaluation {
    let combined = combine_sequences(results).summary();
    if !is_folder {
        return Evaluation::File(combined);
    }
    Evaluation::Folder {
        sequences: sequences
            .iter()
            .zip(results)
            .map(|(s, r)| (s.name.clone(), r.summary()))
            .collect(),
        combined,
    }
}

fn evaluate_all(
    sequences: &[LoadedSequence],
    classes: ClassSelection,
    is_folder: bool,
) -> anyhow::Result<Evaluation> {
    let results = evaluate_class(sequences, classes)?;
    Ok(evaluation_of(sequences, &results, is_folder))
}

fn evaluate_per_class(sequences: &[LoadedSequence], is_folder: bool) -> anyhow::Result<Output> {
    let mut class_ids: Vec<i64> = sequences
        .iter()
        .flat_map(|s| {
            s.gt.iter()
                .filter(|a| a.considered)
                .chain(s.pred.iter())
                .map(|a| a.class)
        })
        .collect();
    class_ids.sort_unstable();
    class_ids.dedup();
    let mut classes = BTreeMap::new();
    let mut combined_per_class = Vec::new();
    for &c in &class_ids {
        let results = evaluate_class(sequences, ClassSelection::Only(c))?;
        combined_per_class.push(combine_sequences(&results));
        classes.insert(c, evaluation_of(sequences, &results, is_folder));
    }
    Ok(Output::PerClass {
        classes,
        class_averaged: combine_classes_class_averaged(&combined_per_class),
        detection_averaged: (!combined_per_class.is_empty())
            .then(|| combine_sequences(&combined_per_class).summary()),
    })
}

fn print_tables(out: &mut impl Write, output: &Output) -> io::Result<()> {
    match output {
        Output::Single(e) => print_evaluation(out, None, e),
        Output::PerClass {
            classes,
            class_averaged,
            detection_averaged,
        } => {
            for (c, e) in classes {
                print_evaluation(out, Some(&format!("class {c}")), e)?;
            }
            let mut rows = Vec::new();
            if let Some(s) = class_averaged {
                rows.push(("class averaged".to_owned(), *s));
            }
            if let Some(s) = detection_averaged {
                rows.push(("detection averaged".to_owned(), *s));
            }
            if !rows.is_empty() {
                print_rows(out, "all classes", &rows)?;
            }
            Ok(())
        }
    }
}

fn print_evaluation(out: &mut impl Write, title: Option<&str>, e: &Evaluation) -> io::Result<()> {
    let title = title.unwrap_or("all objects");
    match e {
        Evaluation::File(s) => print_rows(out, title, &[("COMBINED".to_owned(), *s)]),
        Evaluation::Folder {
            sequences,
            combined,
        } => {
            let mut rows: Vec<(String, Summary)> =
                sequences.iter().map(|(n, s)| (n.clone(), *s)).collect();
            rows.push(("COMBINED".to_owned(), *combined));
            print_rows(out, title, &rows)
        }
    }
}

/// Prints three blocks (HOTA, CLEAR, Identity), one row per sequence; ratios
/// as fractions with four decimals.
fn print_rows(out: &mut impl Write, title: &str, rows: &[(String, Summary)]) -> io::Result<()> {
    let width = rows
        .iter()
        .map(|(n, _)| n.len())
        .chain(std::iter::once("Identity: ".len() + title.len()))
        .max()
        .unwrap_or(0);
    type Column = (&'static str, fn(&Summary) -> String);
    let blocks: [(&str, Vec<Column>); 3] = [
        (
            "HOTA",
            vec![
                ("HOTA", |s| format!("{:>9.4}", s.hota)),
                ("DetA", |s| format!("{:>9.4}", s.det_a)),
                ("AssA", |s| format!("{:>9.4}", s.ass_a)),
                ("DetRe", |s| format!("{:>9.4}", s.det_re)),
                ("DetPr", |s| format!("{:>9.4}", s.det_pr)),
                ("AssRe", |s| format!("{:>9.4}", s.ass_re)),
                ("AssPr", |s| format!("{:>9.4}", s.ass_pr)),
                ("LocA", |s| format!("{:>9.4}", s.loc_a)),
            ],
        ),
        (
            "CLEAR",
            vec![
                ("MOTA", |s| format!("{:>9.4}", s.mota)),
                ("MOTP", |s| format!("{:>9.4}", s.motp)),
                ("Recall", |s| format!("{:>9.4}", s.recall)),
                ("Precision", |s| format!("{:>9.4}", s.precision)),
                ("MT", |s| format!("{:>9}", s.mt)),
                ("PT", |s| format!("{:>9}", s.pt)),
                ("ML", |s| format!("{:>9}", s.ml)),
                ("FP", |s| format!("{:>9}", s.fp)),
                ("FN", |s| format!("{:>9}", s.fn_)),
                ("IDSW", |s| format!("{:>9}", s.idsw)),
                ("Frag", |s| format!("{:>9}", s.frag)),
            ],
        ),
        (
            "Identity",
            vec![
                ("IDF1", |s| format!("{:>9.4}", s.idf1)),
                ("IDR", |s| format!("{:>9.4}", s.idr)),
                ("IDP", |s| format!("{:>9.4}", s.idp)),
            ],
        ),
    ];
    for (block, columns) in &blocks {
        let mut header = format!("{:<width$}", format!("{block}: {title}"));
        for (name, _) in columns {
            header.push_str(&format!(" {name:>9}"));
        }
        writeln!(out, "{header}")?;
        for (name, s) in rows {
            let mut line = format!("{name:<width$}");
            for (_, cell) in columns {
                line.push(' ');
                line.push_str(&cell(s));
            }
            writeln!(out, "{line}")?;
        }
        writeln!(out)?;
    }
    Ok(())
}
