//! Autopilot parameter files (`firmware-config/`) checked against parameter metadata tables,
//! without a simulator or an autopilot.
//!
//! A table (`firmware-config/metadata/*.tsv`, written by `scripts/firmware_extract_params.py`)
//! lists each parameter's name, storage type, documented range, enumeration values and bitmask
//! bits. [`check`] reads a parameter file, ArduPilot's `.parm` (`NAME VALUE` or `NAME,VALUE`,
//! `#` comments) or QGroundControl's `.params` for PX4 (`vehicle-id component-id name value
//! type`, tab or space separated), and reports every problem with its line: a name the table
//! does not know, a value that is not a number of the parameter's type (an integer within
//! int8/int16/int32 for integer types), outside the documented range, not one of the
//! enumeration's values, with bits the bitmask does not document, a name set twice, and for
//! PX4 a type column that disagrees with the table.
//!
//! ```
//! use mgmot::firmware::{check, Autopilot, ParamTable};
//! let table = ParamTable::parse("SERIAL2_BAUD\tint32\t\t\t921:921600|57:57600\t\n").unwrap();
//! assert!(check(Autopilot::ArduPilot, "SERIAL2_BAUD 921\n", &table).is_empty());
//! let problems = check(Autopilot::ArduPilot, "SERIAL2_BAUD 9.5\n", &table);
//! assert_eq!(problems[0].line, 1);
//! ```

use std::collections::BTreeMap;
use std::fmt;
use std::path::{Path, PathBuf};

/// The ArduCopter table shipped in `firmware-config/metadata/`.
pub const ARDUPILOT_COPTER_TABLE: &str =
    include_str!("../firmware-config/metadata/ardupilot-copter-params.tsv");
/// The PX4 table shipped in `firmware-config/metadata/`.
pub const PX4_TABLE: &str = include_str!("../firmware-config/metadata/px4-params.tsv");

/// The largest parameter file or table read (bytes): these files are a few kilobytes.
const MAX_FILE_BYTES: u64 = 16 * 1024 * 1024;

/// Which autopilot a parameter file is for (decides its format).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Autopilot {
    /// ArduPilot `.parm` / `.param`: `NAME VALUE` or `NAME,VALUE` per line, `#` comments.
    ArduPilot,
    /// QGroundControl `.params` for PX4: `vehicle-id component-id name value type` per line.
    Px4,
}

impl Autopilot {
    /// The metadata table shipped for this autopilot.
    pub fn shipped_table(self) -> &'static str {
        match self {
            Autopilot::ArduPilot => ARDUPILOT_COPTER_TABLE,
            Autopilot::Px4 => PX4_TABLE,
        }
    }
}

/// A parameter's storage type.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ParamType {
    /// Signed 8-bit integer (ArduPilot `AP_Int8`, `AP_Enum`).
    Int8,
    /// Signed 16-bit integer (ArduPilot `AP_Int16`, `AP_Enum16`).
    Int16,
    /// Signed 32-bit integer (ArduPilot `AP_Int32`; every PX4 integer, enum and boolean).
    Int32,
    /// 32-bit float.
    Float,
    /// Not found by the extraction: only "a finite number" is checked.
    Unknown,
}

impl ParamType {
    fn parse(s: &str) -> Option<Self> {
        Some(match s {
            "int8" => ParamType::Int8,
            "int16" => ParamType::Int16,
            "int32" => ParamType::Int32,
            "float" => ParamType::Float,
            "unknown" => ParamType::Unknown,
            _ => return None,
        })
    }

    /// The inclusive range of an integer type; `None` for float and unknown.
    pub fn int_range(self) -> Option<(i64, i64)> {
        match self {
            ParamType::Int8 => Some((i8::MIN.into(), i8::MAX.into())),
            ParamType::Int16 => Some((i16::MIN.into(), i16::MAX.into())),
            ParamType::Int32 => Some((i32::MIN.into(), i32::MAX.into())),
            ParamType::Float | ParamType::Unknown => None,
        }
    }

    /// The MAV_PARAM_TYPE a QGroundControl `.params` file gives this type (6 INT32, 9 REAL32).
    fn mav_param_type(self) -> Option<u32> {
        match self {
            ParamType::Int8 => Some(2),
            ParamType::Int16 => Some(4),
            ParamType::Int32 => Some(6),
            ParamType::Float => Some(9),
            ParamType::Unknown => None,
        }
    }
}

impl fmt::Display for ParamType {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            ParamType::Int8 => "int8",
            ParamType::Int16 => "int16",
            ParamType::Int32 => "int32",
            ParamType::Float => "float",
            ParamType::Unknown => "unknown",
        })
    }
}

/// One parameter of a metadata table.
#[derive(Debug, Clone, PartialEq)]
pub struct ParamSpec {
    /// Storage type.
    pub ty: ParamType,
    /// Documented minimum, if any.
    pub min: Option<f64>,
    /// Documented maximum, if any.
    pub max: Option<f64>,
    /// Enumeration values (empty: any value of the type).
    pub values: Vec<f64>,
    /// Documented bitmask bits (empty: not a bitmask).
    pub bits: Vec<u32>,
}

/// A parameter metadata table: name -> [`ParamSpec`].
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ParamTable {
    params: BTreeMap<String, ParamSpec>,
}

/// A table line that cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum FirmwareError {
    /// A file could not be read.
    #[error("{path}: {source}")]
    Io {
        /// The file.
        path: PathBuf,
        /// What went wrong.
        source: std::io::Error,
    },
    /// A file larger than any parameter file or table.
    #[error("{path}: larger than {MAX_FILE_BYTES} bytes")]
    TooLarge {
        /// The file.
        path: PathBuf,
    },
    /// A malformed metadata table line.
    #[error("metadata table line {line}: {message}")]
    Table {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        message: String,
    },
}

impl ParamTable {
    /// Parses a table: `#` lines are comments, every other line is
    /// `name<TAB>type<TAB>min<TAB>max<TAB>values<TAB>bitmask`, where values and bitmask are
    /// `KEY:label|KEY:label` (labels are ignored).
    pub fn parse(text: &str) -> Result<Self, FirmwareError> {
        let mut params = BTreeMap::new();
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            if raw.trim().is_empty() || raw.starts_with('#') {
                continue;
            }
            let err = |message: String| FirmwareError::Table { line, message };
            let cols: Vec<&str> = raw.split('\t').collect();
            if cols.len() < 2 {
                return Err(err(format!("expected name and type, got {raw:?}")));
            }
            let ty = ParamType::parse(cols[1].trim())
                .ok_or_else(|| err(format!("unknown type {:?}", cols[1])))?;
            let bound = |c: Option<&&str>| -> Result<Option<f64>, FirmwareError> {
                match c.map(|s| s.trim()).filter(|s| !s.is_empty()) {
                    None => Ok(None),
                    Some(s) => s
                        .parse::<f64>()
                        .ok()
                        .filter(|v| v.is_finite())
                        .map(Some)
                        .ok_or_else(|| err(format!("bound {s:?} is not a number"))),
                }
            };
            let mut values = Vec::new();
            for k in table_keys(cols.get(4).copied()) {
                values.push(
                    k.parse::<f64>()
                        .map_err(|_| err(format!("value key {k:?} is not a number")))?,
                );
            }
            let mut bits = Vec::new();
            for k in table_keys(cols.get(5).copied()) {
                bits.push(
                    k.parse::<u32>()
                        .ok()
                        .filter(|b| *b < 64)
                        .ok_or_else(|| err(format!("bit {k:?} is not 0..=63")))?,
                );
            }
            let spec = ParamSpec {
                ty,
                min: bound(cols.get(2))?,
                max: bound(cols.get(3))?,
                values,
                bits,
            };
            params.insert(cols[0].trim().to_owned(), spec);
        }
        Ok(Self { params })
    }

    /// Reads and parses a table file.
    pub fn load(path: &Path) -> Result<Self, FirmwareError> {
        Self::parse(&read_small(path)?)
    }

    /// The parameter called `name`, if the table has it.
    pub fn get(&self, name: &str) -> Option<&ParamSpec> {
        self.params.get(name)
    }

    /// How many parameters the table has.
    pub fn len(&self) -> usize {
        self.params.len()
    }

    /// Whether the table has no parameters.
    pub fn is_empty(&self) -> bool {
        self.params.is_empty()
    }
}

/// The keys of a `KEY:label|KEY:label` table column.
fn table_keys(column: Option<&str>) -> Vec<&str> {
    column
        .map(|s| {
            s.split('|')
                .filter_map(|item| item.split(':').next())
                .map(str::trim)
                .filter(|k| !k.is_empty())
                .collect()
        })
        .unwrap_or_default()
}

/// One problem in a parameter file.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Problem {
    /// 1-based line number.
    pub line: usize,
    /// The parameter's name, when the line has one.
    pub name: Option<String>,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.name {
            Some(n) => write!(f, "line {}: {n}: {}", self.line, self.message),
            None => write!(f, "line {}: {}", self.line, self.message),
        }
    }
}

/// One `NAME VALUE` assignment of a parameter file.
struct Assignment<'a> {
    line: usize,
    name: &'a str,
    value: &'a str,
    /// PX4 only: the MAV_PARAM_TYPE column.
    mav_type: Option<&'a str>,
}

fn assignments<'a>(
    autopilot: Autopilot,
    text: &'a str,
    problems: &mut Vec<Problem>,
) -> Vec<Assignment<'a>> {
    let mut out = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let line = i + 1;
        let content = raw.split('#').next().unwrap_or_default().trim();
        if content.is_empty() {
            continue;
        }
        let fields: Vec<&str> = match autopilot {
            Autopilot::ArduPilot => content
                .split(|c: char| c == ',' || c.is_whitespace())
                .filter(|s| !s.is_empty())
                .collect(),
            Autopilot::Px4 => content.split_whitespace().collect(),
        };
        let bad = |message: String| Problem {
            line,
            name: None,
            message,
        };
        match (autopilot, fields.as_slice()) {
            (Autopilot::ArduPilot, [name, value]) => out.push(Assignment {
                line,
                name,
                value,
                mav_type: None,
            }),
            (Autopilot::ArduPilot, _) => problems.push(bad(format!(
                "expected `NAME VALUE` or `NAME,VALUE`, got {content:?}"
            ))),
            (Autopilot::Px4, [vehicle, component, name, value, ty]) => {
                for (what, id) in [("vehicle id", vehicle), ("component id", component)] {
                    if !matches!(id.parse::<u8>(), Ok(1..=255)) {
                        problems.push(Problem {
                            line,
                            name: Some((*name).to_owned()),
                            message: format!("{what} {id:?} is not 1..=255"),
                        });
                    }
                }
                out.push(Assignment {
                    line,
                    name,
                    value,
                    mav_type: Some(ty),
                });
            }
            (Autopilot::Px4, _) => problems.push(bad(format!(
                "expected `vehicle-id component-id name value type`, got {content:?}"
            ))),
        }
    }
    out
}

/// Whether `s` is a plain decimal integer (`-12`, `+3`, `0`), the only integer form accepted.
fn parse_int(s: &str) -> Option<i64> {
    let digits = s.strip_prefix(['-', '+']).unwrap_or(s);
    if digits.is_empty() || !digits.bytes().all(|b| b.is_ascii_digit()) {
        return None;
    }
    s.parse().ok()
}

/// Checks one value against its spec; the message says what is wrong.
fn check_value(spec: &ParamSpec, value: &str) -> Result<(), String> {
    let v = match spec.ty.int_range() {
        Some((lo, hi)) => {
            let Some(n) = parse_int(value) else {
                return Err(format!(
                    "{value:?} is not an integer ({} parameter)",
                    spec.ty
                ));
            };
            if n < lo || n > hi {
                return Err(format!("{n} does not fit {} ({lo}..={hi})", spec.ty));
            }
            n as f64
        }
        None => match value.parse::<f64>() {
            Ok(v) if v.is_finite() => v,
            _ => return Err(format!("{value:?} is not a finite number")),
        },
    };
    match (spec.min, spec.max) {
        (Some(lo), _) if v < lo => return Err(format!("{value} is below the minimum {lo}")),
        (_, Some(hi)) if v > hi => return Err(format!("{value} is above the maximum {hi}")),
        _ => {}
    }
    if !spec.values.is_empty() && !spec.values.contains(&v) {
        let allowed: Vec<String> = spec.values.iter().map(|k| k.to_string()).collect();
        return Err(format!(
            "{value} is not one of the documented values {}",
            allowed.join(", ")
        ));
    }
    if !spec.bits.is_empty() {
        let mask = spec.bits.iter().fold(0u64, |m, b| m | (1u64 << b));
        // an integer type (a bitmask on a float parameter is checked as a whole number)
        if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
            return Err(format!("{value} is not a bitmask (a non-negative integer)"));
        }
        let undocumented = (v as u64) & !mask;
        if undocumented != 0 {
            return Err(format!(
                "{value} sets bits the bitmask does not document (0x{undocumented:x})"
            ));
        }
    }
    Ok(())
}

/// Checks a parameter file's text against a table; every problem, in line order.
pub fn check(autopilot: Autopilot, text: &str, table: &ParamTable) -> Vec<Problem> {
    let mut problems = Vec::new();
    let mut seen: BTreeMap<&str, usize> = BTreeMap::new();
    for a in assignments(autopilot, text, &mut problems) {
        let problem = |message: String| Problem {
            line: a.line,
            name: Some(a.name.to_owned()),
            message,
        };
        if let Some(first) = seen.insert(a.name, a.line) {
            problems.push(problem(format!("set again (first on line {first})")));
        }
        let Some(spec) = table.get(a.name) else {
            problems.push(problem("not a parameter in the metadata table".to_owned()));
            continue;
        };
        if let Err(message) = check_value(spec, a.value) {
            problems.push(problem(message));
        }
        if let (Some(ty), Some(expected)) = (a.mav_type, spec.ty.mav_param_type()) {
            if ty.parse::<u32>().ok() != Some(expected) {
                problems.push(problem(format!(
                    "type column {ty:?}, but the parameter is {} (MAV_PARAM_TYPE {expected})",
                    spec.ty
                )));
            }
        }
    }
    problems.sort_by_key(|p| p.line);
    problems
}

/// Reads a parameter file and checks it against a table.
pub fn check_file(
    autopilot: Autopilot,
    path: &Path,
    table: &ParamTable,
) -> Result<Vec<Problem>, FirmwareError> {
    Ok(check(autopilot, &read_small(path)?, table))
}

fn read_small(path: &Path) -> Result<String, FirmwareError> {
    let io = |source| FirmwareError::Io {
        path: path.to_owned(),
        source,
    };
    let meta = std::fs::metadata(path).map_err(io)?;
    if !meta.is_file() {
        return Err(io(std::io::Error::other("not a regular file")));
    }
    if meta.len() > MAX_FILE_BYTES {
        return Err(FirmwareError::TooLarge {
            path: path.to_owned(),
        });
    }
    std::fs::read_to_string(path).map_err(io)
}

#[cfg(test)]
mod tests {
    use super::*;

    const TABLE: &str = "# comment\n\
        SERIAL2_BAUD\tint32\t\t\t57:57600|921:921600\t\n\
        MNT1_PITCH_MIN\tint16\t-90\t90\t\t\n\
        MNT1_TYPE\tint8\t\t\t0:None|1:Servo|6:Gremsy\t\n\
        MAV3_OPTIONS\tint16\t\t\t\t1:Don't forward|2:Ignore Streamrate\n\
        CAM1_DURATION\tfloat\t0\t5\t\t\n\
        ODD\tunknown\t\t\t\t\n\
        MAV_1_MODE\tint32\t\t\t0:Normal|2:Onboard\t\n\
        MNT_RATE_YAW\tfloat\t1.0\t90.0\t\t\n";

    fn table() -> ParamTable {
        ParamTable::parse(TABLE).unwrap()
    }

    fn messages(ap: Autopilot, text: &str) -> Vec<(usize, String)> {
        check(ap, text, &table())
            .into_iter()
            .map(|p| (p.line, p.to_string()))
            .collect()
    }

    #[test]
    fn table_parses_types_bounds_values_and_bits() {
        let t = table();
        assert_eq!(t.len(), 8);
        let p = t.get("MNT1_PITCH_MIN").unwrap();
        assert_eq!(
            (p.ty, p.min, p.max),
            (ParamType::Int16, Some(-90.0), Some(90.0))
        );
        assert_eq!(t.get("MNT1_TYPE").unwrap().values, vec![0.0, 1.0, 6.0]);
        assert_eq!(t.get("MAV3_OPTIONS").unwrap().bits, vec![1, 2]);
        assert!(t.get("NOPE").is_none());
        assert!(matches!(
            ParamTable::parse("X\tint64\n"),
            Err(FirmwareError::Table { line: 1, .. })
        ));
        assert!(matches!(
            ParamTable::parse("# c\nX\tint8\tlow\n"),
            Err(FirmwareError::Table { line: 2, .. })
        ));
    }

    #[test]
    fn good_ardupilot_file_has_no_problems() {
        let text = "# header\n\nSERIAL2_BAUD 921\nMNT1_PITCH_MIN,-90\nMNT1_TYPE\t6 # gimbal\n\
                    MAV3_OPTIONS 6\nCAM1_DURATION 0.5\nODD 3.25\n";
        assert_eq!(messages(Autopilot::ArduPilot, text), vec![]);
    }

    #[test]
    fn every_ardupilot_problem_is_reported_with_its_line() {
        let text = "NOPE 1\nSERIAL2_BAUD 921.0\nMNT1_PITCH_MIN -91\nMNT1_TYPE 3\n\
                    MAV3_OPTIONS 1\nCAM1_DURATION nan\nMNT1_PITCH_MIN 40000\nSERIAL2_BAUD\n\
                    ODD x\nCAM1_DURATION 1e1\n";
        let got = messages(Autopilot::ArduPilot, text);
        let lines: Vec<usize> = got.iter().map(|(l, _)| *l).collect();
        // lines 7 and 10 twice: set again, and a bad value
        assert_eq!(lines, vec![1, 2, 3, 4, 5, 6, 7, 7, 8, 9, 10, 10], "{got:?}");
        let text_of = |l: usize| {
            got.iter()
                .filter(|(n, _)| *n == l)
                .map(|(_, m)| m.as_str())
                .collect::<Vec<_>>()
                .join(" / ")
        };
        assert!(text_of(1).contains("not a parameter"), "{}", text_of(1));
        assert!(text_of(2).contains("not an integer"), "{}", text_of(2));
        assert!(
            text_of(3).contains("below the minimum -90"),
            "{}",
            text_of(3)
        );
        assert!(
            text_of(4).contains("documented values 0, 1, 6"),
            "{}",
            text_of(4)
        );
        assert!(text_of(5).contains("bits the bitmask does not document (0x1)"));
        assert!(text_of(6).contains("finite"), "{}", text_of(6));
        assert!(text_of(7).contains("set again (first on line 3)"));
        assert!(text_of(7).contains("does not fit int16"), "{}", text_of(7));
        assert!(
            text_of(8).contains("expected `NAME VALUE`"),
            "{}",
            text_of(8)
        );
        assert!(text_of(9).contains("finite"), "{}", text_of(9));
        assert!(
            text_of(10).contains("above the maximum 5"),
            "{}",
            text_of(10)
        );
    }

    #[test]
    fn px4_columns_and_types_are_checked() {
        let good = "# Vehicle-Id Component-Id Name Value Type\n1\t1\tMAV_1_MODE\t2\t6\n\
                    1\t1\tMNT_RATE_YAW\t30.5\t9\n";
        assert_eq!(messages(Autopilot::Px4, good), vec![]);
        let bad = "1\t1\tMAV_1_MODE\t2\t9\n0\t1\tMNT_RATE_YAW\t30\t9\nMAV_1_MODE 2\n\
                   1\t1\tMAV_1_MODE\t1\t6\n";
        let got = messages(Autopilot::Px4, bad);
        assert_eq!(got.len(), 5, "{got:?}");
        assert!(got[0].1.contains("type column \"9\""), "{got:?}");
        assert!(got[1].1.contains("vehicle id \"0\""), "{got:?}");
        assert!(got[2].1.contains("expected `vehicle-id"), "{got:?}");
        assert_eq!(got[3].0, 4);
        assert!(got
            .iter()
            .any(|(l, m)| *l == 4 && m.contains("documented values")));
        assert!(got.iter().any(|(l, m)| *l == 4 && m.contains("set again")));
    }

    #[test]
    fn integer_syntax_is_plain_decimal() {
        assert_eq!(parse_int("-12"), Some(-12));
        assert_eq!(parse_int("+3"), Some(3));
        for bad in ["", "-", "1.0", "1e3", "0x10", " 1", "١"] {
            assert_eq!(parse_int(bad), None, "{bad:?}");
        }
    }

    #[test]
    fn shipped_tables_parse() {
        let ap = ParamTable::parse(ARDUPILOT_COPTER_TABLE).unwrap();
        let px4 = ParamTable::parse(PX4_TABLE).unwrap();
        assert_eq!(
            ap.get("SERIAL2_PROTOCOL").map(|p| p.ty),
            Some(ParamType::Int8)
        );
        assert_eq!(ap.get("SERIAL2_BAUD").map(|p| p.ty), Some(ParamType::Int32));
        assert_eq!(
            px4.get("MAV_1_CONFIG").map(|p| p.ty),
            Some(ParamType::Int32)
        );
        assert_eq!(
            px4.get("MNT_RATE_YAW").map(|p| p.ty),
            Some(ParamType::Float)
        );
    }
}
