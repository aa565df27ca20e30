//! What a detector model looks like from the outside: input size, output
//! layout, class names, read from the ONNX graph and its metadata.
//!
//! Ultralytics exports write the metadata keys `names` (a Python dict literal,
//! `{0: 'person', 1: 'bicycle'}`) and `imgsz` (`[640, 640]`, height then
//! width); the project's own export (`train/export.py`) writes the same keys.

use std::path::{Path, PathBuf};

use tract_onnx::prelude::Framework;

use super::DetectError;

/// How the candidates are laid out in the model's output tensor.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OutputLayout {
    /// `(1, 4 + nc, N)`: Ultralytics YOLOv8 / YOLO11 (and the project's model).
    ChannelsFirst,
    /// `(1, N, 4 + nc)`: the same rows transposed, as some exporters write it.
    ChannelsLast,
}

/// A loaded model's interface.
#[derive(Debug, Clone)]
pub struct ModelInfo {
    /// The model file, for error messages.
    pub path: PathBuf,
    /// Name of the image input.
    pub input_name: String,
    /// Input width the model expects (letterbox target).
    pub input_width_px: u32,
    /// Input height the model expects (letterbox target).
    pub input_height_px: u32,
    /// Name of the detection output.
    pub output_name: String,
    /// Layout of the detection output.
    pub layout: OutputLayout,
    /// Number of candidate boxes per inference (N).
    pub num_candidates: usize,
    /// Class names, indexed by class id; its length is the number of classes.
    pub class_names: Vec<String>,
    /// The SeaDronesSee category id of each class (indexed like `class_names`), from the
    /// names ([`category_ids_for`]): what `mgmot detect` writes and what the tracker and
    /// MAVLink carry, whatever order or spelling the model uses.
    pub category_ids: Vec<u32>,
}

impl ModelInfo {
    /// The SeaDronesSee category id of class `class_id` (0, "other object", when out of range).
    pub fn category_id(&self, class_id: usize) -> u32 {
        self.category_ids.get(class_id).copied().unwrap_or(0)
    }
}

/// SeaDronesSee's categories: id 1 swimmer, 2 boat, 3 jetski, 4 life-saving appliance, 5 buoy.
pub const SEADRONESSEE_CATEGORIES: [(u32, &str); 5] = [
    (1, "swimmer"),
    (2, "boat"),
    (3, "jetski"),
    (4, "life_saving_appliances"),
    (5, "buoy"),
];

/// The SeaDronesSee category id a class name stands for, or `None` for a name that is none
/// of the five. Case, spaces, hyphens and underscores do not matter; common synonyms of
/// other datasets and exports are accepted (`person` for swimmer, `life ring` for a
/// life-saving appliance, ...).
pub fn seadronessee_category(name: &str) -> Option<u32> {
    let key: String = name
        .chars()
        .filter(|c| !matches!(c, ' ' | '_' | '-'))
        .flat_map(char::to_lowercase)
        .collect();
    let id = match key.as_str() {
        "swimmer"
        | "swimmers"
        | "swimmerwithlifejacket"
        | "person"
        | "people"
        | "human"
        | "personinwater" => 1,
        "boat" | "boats" | "ship" | "vessel" => 2,
        "jetski" | "jetskis" | "personalwatercraft" => 3,
        "lifesavingappliances"
        | "lifesavingappliance"
        | "lifebuoy"
        | "lifering"
        | "liferaft"
        | "lifejacket" => 4,
        "buoy" | "buoys" => 5,
        _ => return None,
    };
    Some(id)
}

/// The SeaDronesSee category id of each class name, and the names that are none of the five.
///
/// A model whose names all map (mgmot's own, or an Ultralytics export trained on
/// SeaDronesSee, in any order) gets their ids. Names that do not map get 0 ("other
/// object"), unless none of the names maps at all (a model with no names, or `class0`,
/// `class1`, ...): then class `k` is category `k + 1`, SeaDronesSee's order.
pub fn category_ids_for(names: &[String]) -> (Vec<u32>, Vec<String>) {
    let mapped: Vec<Option<u32>> = names.iter().map(|n| seadronessee_category(n)).collect();
    let unknown: Vec<String> = names
        .iter()
        .zip(&mapped)
        .filter(|(_, m)| m.is_none())
        .map(|(n, _)| n.clone())
        .collect();
    if mapped.iter().all(Option::is_none) {
        let ids = (1..=names.len())
            .map(|k| u32::try_from(k).unwrap_or(u32::MAX))
            .collect();
        return (ids, unknown);
    }
    (
        mapped.into_iter().map(|m| m.unwrap_or(0)).collect(),
        unknown,
    )
}

/// The metadata entries mgmot reads from an ONNX file.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ModelMetadata {
    /// Class names from `names`, when present.
    pub class_names: Option<Vec<String>>,
    /// `(height, width)` from `imgsz`, when present.
    pub image_size_hw: Option<(u32, u32)>,
}

/// Reads the metadata of an ONNX file already in memory (`path` only names it in errors).
///
/// This parses the protobuf itself (with tract-onnx's ONNX definitions), so it
/// works the same whichever backend runs the model.
pub fn read_metadata(path: &Path, bytes: &[u8]) -> Result<ModelMetadata, DetectError> {
    let proto = tract_onnx::onnx()
        .proto_model_for_read(&mut &bytes[..])
        .map_err(|e| DetectError::ModelParse {
            path: path.to_path_buf(),
            message: format!("{e:#}"),
        })?;
    if proto.graph.is_none() {
        return Err(DetectError::ModelParse {
            path: path.to_path_buf(),
            message: "the file holds no graph".into(),
        });
    }
    let mut meta = ModelMetadata::default();
    for prop in &proto.metadata_props {
        let bad = |problem: String| DetectError::BadMetadata {
            path: path.to_path_buf(),
            key: prop.key.clone(),
            problem,
        };
        match prop.key.as_str() {
            "names" => meta.class_names = Some(parse_class_names(&prop.value).map_err(bad)?),
            "imgsz" => meta.image_size_hw = Some(parse_image_size(&prop.value).map_err(bad)?),
            _ => {}
        }
    }
    Ok(meta)
}

/// Parses class names written as a Python dict literal (`{0: 'swimmer', 1: 'boat'}`,
/// Ultralytics), a JSON object (`{"0": "swimmer"}`) or a JSON list (`["swimmer", "boat"]`).
///
/// Ids must be exactly `0..n`.
pub fn parse_class_names(text: &str) -> Result<Vec<String>, String> {
    let t = text.trim();
    if let Ok(list) = serde_json::from_str::<Vec<String>>(t) {
        return Ok(list);
    }
    let inner = t
        .strip_prefix('{')
        .and_then(|s| s.strip_suffix('}'))
        .ok_or_else(|| format!("expected a dict such as {{0: 'swimmer'}} or a list, got `{t}`"))?;
    let mut entries: Vec<(usize, String)> = Vec::new();
    let mut rest = inner.trim_start();
    while !rest.is_empty() {
        let (key, after_key) = take_token(rest)?;
        let id: usize = key
            .parse()
            .map_err(|_| format!("class id `{key}` is not a non-negative integer"))?;
        let after_colon = after_key
            .trim_start()
            .strip_prefix(':')
            .ok_or_else(|| format!("expected `:` after class id {id}"))?;
        let (name, after_name) = take_token(after_colon.trim_start())?;
        entries.push((id, name));
        rest = after_name.trim_start();
        rest = rest.strip_prefix(',').unwrap_or(rest).trim_start();
    }
    entries.sort_by_key(|(id, _)| *id);
    for (i, (id, _)) in entries.iter().enumerate() {
        if *id != i {
            return Err(format!(
                "class ids must be 0..n without gaps; id {i} is missing"
            ));
        }
    }
    if entries.is_empty() {
        return Err("no class names".into());
    }
    Ok(entries.into_iter().map(|(_, n)| n).collect())
}

/// One quoted string or bare word at the start of `s`; returns it and the rest.
fn take_token(s: &str) -> Result<(String, &str), String> {
    let mut chars = s.char_indices();
    match chars.next() {
        Some((_, q @ ('\'' | '"'))) => {
            let mut out = String::new();
            let mut escaped = false;
            for (i, c) in chars {
                if escaped {
                    out.push(c);
                    escaped = false;
                } else if c == '\\' {
                    escaped = true;
                } else if c == q {
                    return Ok((out, &s[i + c.len_utf8()..]));
                } else {
                    out.push(c);
                }
            }
            Err(format!("unterminated string in `{s}`"))
        }
        Some(_) => {
            let end = s.find([':', ',', '}']).unwrap_or(s.len());
            let word = s[..end].trim();
            if word.is_empty() {
                return Err(format!("expected a value at `{s}`"));
            }
            Ok((word.to_string(), &s[end..]))
        }
        None => Err("unexpected end of text".into()),
    }
}

/// Parses `imgsz`: `[H, W]`, `[S]` or `S`.
pub fn parse_image_size(text: &str) -> Result<(u32, u32), String> {
    let t = text.trim().trim_start_matches('[').trim_end_matches(']');
    let nums: Result<Vec<u32>, _> = t
        .split(',')
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::parse::<u32>)
        .collect();
    match nums.map_err(|e| format!("`{text}`: {e}"))?.as_slice() {
        [s] if *s > 0 => Ok((*s, *s)),
        [h, w] if *h > 0 && *w > 0 => Ok((*h, *w)),
        _ => Err(format!("expected [height, width], got `{text}`")),
    }
}

/// Decides the layout of an output of shape `dims` (batch first) holding
/// `num_classes` classes, or says why it is not a detector output.
pub fn detect_layout(
    dims: &[i64],
    num_classes: Option<usize>,
) -> Result<(OutputLayout, usize, usize), String> {
    let [batch, a, b] = dims else {
        return Err(format!(
            "expected rank 3 (1, 4 + nc, N) or (1, N, 4 + nc), got shape {dims:?}"
        ));
    };
    if *batch != 1 && *batch != -1 {
        return Err(format!(
            "batch dimension is {batch}, expected 1 (shape {dims:?})"
        ));
    }
    let (a, b) = (*a, *b);
    if a <= 0 || b <= 0 {
        return Err(format!("dynamic or empty dimensions in {dims:?}"));
    }
    let (a, b) = (a as usize, b as usize);
    let layout = match num_classes {
        Some(nc) if a == 4 + nc && b != 4 + nc => OutputLayout::ChannelsFirst,
        Some(nc) if b == 4 + nc && a != 4 + nc => OutputLayout::ChannelsLast,
        Some(nc) if a == 4 + nc => OutputLayout::ChannelsFirst,
        Some(nc) => {
            return Err(format!(
                "neither dimension of {dims:?} is 4 + {nc} (4 box values + {nc} classes)"
            ))
        }
        // Without class names: the candidate count dwarfs the row count in
        // every real detector (N = 8400 at 640 px).
        None if a < b && a > 4 => OutputLayout::ChannelsFirst,
        None if b < a && b > 4 => OutputLayout::ChannelsLast,
        None => return Err(format!("cannot tell rows from candidates in {dims:?}")),
    };
    Ok(match layout {
        OutputLayout::ChannelsFirst => (layout, a - 4, b),
        OutputLayout::ChannelsLast => (layout, b - 4, a),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ultralytics_names_parse() {
        assert_eq!(
            parse_class_names("{0: 'swimmer', 1: 'boat', 2: \"life jacket\"}").unwrap(),
            vec!["swimmer", "boat", "life jacket"]
        );
        assert_eq!(parse_class_names("[\"a\", \"b\"]").unwrap(), vec!["a", "b"]);
        assert_eq!(
            parse_class_names("{\"1\": \"b\", \"0\": \"a\"}").unwrap(),
            vec!["a", "b"]
        );
        assert_eq!(parse_class_names("{0: 'it\\'s'}").unwrap(), vec!["it's"]);
    }

    #[test]
    fn class_names_map_to_seadronessee_ids_in_any_order() {
        let names = |v: &[&str]| v.iter().map(|s| (*s).to_owned()).collect::<Vec<_>>();
        let (ids, unknown) = category_ids_for(&names(&[
            "swimmer",
            "boat",
            "jetski",
            "life_saving_appliances",
            "buoy",
        ]));
        assert_eq!(ids, [1, 2, 3, 4, 5]);
        assert!(unknown.is_empty());
        // An export in another order and spelling lands on the same ids.
        let (ids, _) =
            category_ids_for(&names(&["Buoy", "life ring", "Jet-Ski", "person", "Boat"]));
        assert_eq!(ids, [5, 4, 3, 1, 2]);
        // A name that is none of the five is "other object" (0), the rest still map.
        let (ids, unknown) = category_ids_for(&names(&["swimmer", "kayak"]));
        assert_eq!(ids, [1, 0]);
        assert_eq!(unknown, ["kayak"]);
        // No name maps (no metadata): SeaDronesSee's order.
        let (ids, unknown) = category_ids_for(&names(&["class0", "class1"]));
        assert_eq!(ids, [1, 2]);
        assert_eq!(unknown.len(), 2);
        for (id, name) in SEADRONESSEE_CATEGORIES {
            assert_eq!(seadronessee_category(name), Some(id));
        }
    }

    #[test]
    fn bad_names_are_errors() {
        assert!(parse_class_names("{0: 'a', 2: 'c'}")
            .unwrap_err()
            .contains("id 1"));
        assert!(parse_class_names("swimmer").is_err());
        assert!(parse_class_names("{}").is_err());
        assert!(parse_class_names("{x: 'a'}").is_err());
        assert!(parse_class_names("{0: 'a").is_err());
    }

    #[test]
    fn image_size_parses() {
        assert_eq!(parse_image_size("[640, 480]").unwrap(), (640, 480));
        assert_eq!(parse_image_size("320").unwrap(), (320, 320));
        assert!(parse_image_size("[0, 3]").is_err());
        assert!(parse_image_size("[a]").is_err());
    }

    #[test]
    fn layouts() {
        assert_eq!(
            detect_layout(&[1, 6, 2100], Some(2)).unwrap(),
            (OutputLayout::ChannelsFirst, 2, 2100)
        );
        assert_eq!(
            detect_layout(&[1, 8400, 84], Some(80)).unwrap(),
            (OutputLayout::ChannelsLast, 80, 8400)
        );
        assert_eq!(
            detect_layout(&[1, 84, 8400], None).unwrap(),
            (OutputLayout::ChannelsFirst, 80, 8400)
        );
        assert!(detect_layout(&[1, 7, 2100], Some(2)).is_err());
        assert!(detect_layout(&[1, 300, 6, 1], Some(2)).is_err());
        assert!(detect_layout(&[2, 6, 2100], Some(2)).is_err());
    }
}
