//! SeaDronesSee JSON (COCO layout): images carrying the drone's `meta`, annotations with an
//! optional `track_id`, an optional `videos` list.
//!
//! Images are grouped into sequences by `video_id` (with `videos`), else by
//! `source.folder_name` / `source.video`, else into one sequence; within a sequence they are
//! ordered by `source.frame_no` (else `frame_index`, else image id).

use super::error::{parse_json, read_json, FormatError};
use crate::geo::{FrameMetadata, GeoError};
use serde::{Deserialize, Serialize};
use std::collections::{BTreeMap, HashMap};
use std::path::Path;

/// Frame rate assumed for `source.frame_no` when images carry no `date_time` (DJI videos of
/// the data set are 30 fps).
pub const DEFAULT_VIDEO_FPS: f64 = 30.0;

/// Largest height above the take-off point (m) a file may give, either sign: no drone flies
/// 100 km up, and larger values could overflow when frames are interpolated.
pub const MAX_HEIGHT_M: f64 = 100_000.0;

/// The whole file.
#[derive(Debug, Clone, Default, Serialize, Deserialize)]
pub struct Dataset {
    /// Frames.
    pub images: Vec<Image>,
    /// Boxes (ground truth).
    #[serde(default)]
    pub annotations: Vec<Annotation>,
    /// Category ids and names.
    #[serde(default)]
    pub categories: Vec<Category>,
    /// Optional explicit videos (sequence names).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub videos: Option<Vec<Video>>,
}

/// One frame.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Image {
    /// Unique image id.
    pub id: u64,
    /// Image file name.
    #[serde(default)]
    pub file_name: String,
    /// Width (px).
    pub width: u32,
    /// Height (px).
    pub height: u32,
    /// Where the frame comes from (video and frame number).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<Source>,
    /// Capture time, ISO 8601 (`2020-08-25T14:19:21.647133`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub date_time: Option<String>,
    /// Video id when the file has a `videos` list.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video_id: Option<u64>,
    /// Frame index inside its video, when there is no `source.frame_no`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_index: Option<u64>,
    /// The drone's metadata for this frame.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub meta: Option<Meta>,
}

/// Provenance of a frame.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct Source {
    /// Drone model.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub drone: Option<String>,
    /// Folder (sequence) name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub folder_name: Option<String>,
    /// Video file name.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub video: Option<String>,
    /// Frame number inside the video.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub frame_no: Option<u64>,
}

/// Drone metadata in the data set's convention (angles in degrees, heading clockwise from
/// north, pitch below the horizon; `docs/data-formats.md`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Meta {
    /// Latitude (deg).
    pub latitude: f64,
    /// Longitude (deg).
    pub longitude: f64,
    /// Height above the take-off point (m), taken as the height above the water.
    #[serde(rename = "height_above_takeoff(meter)")]
    pub height_above_takeoff_m: f64,
    /// Gimbal compass bearing, degrees clockwise from north.
    #[serde(rename = "gimbal_heading(degrees)")]
    pub gimbal_heading_deg: f64,
    /// Gimbal pitch, degrees below the horizon (90 = nadir).
    #[serde(rename = "gimbal_pitch(degrees)")]
    pub gimbal_pitch_deg: f64,
    /// Vehicle compass heading (deg).
    #[serde(
        rename = "compass_heading(degrees)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub compass_heading_deg: Option<f64>,
    /// Ground speed (m/s).
    #[serde(
        rename = "speed(m/s)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub speed_mps: Option<f64>,
    /// Speed component x (m/s), as the DJI log reports it.
    #[serde(
        rename = "xspeed(m/s)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub xspeed_mps: Option<f64>,
    /// Speed component y (m/s).
    #[serde(
        rename = "yspeed(m/s)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub yspeed_mps: Option<f64>,
    /// Speed component z (m/s).
    #[serde(
        rename = "zspeed(m/s)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub zspeed_mps: Option<f64>,
    /// UTC time of the log record.
    #[serde(
        rename = "datetime(utc)",
        default,
        skip_serializing_if = "Option::is_none"
    )]
    pub datetime_utc: Option<String>,
    /// Name of the extracted image.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub image_name: Option<String>,
}

impl Meta {
    /// The frame's camera geometry input (paper Sec. 3.1 reading of the metadata).
    pub fn to_frame_metadata(&self) -> Result<FrameMetadata, GeoError> {
        FrameMetadata::from_seadronessee(
            self.latitude,
            self.longitude,
            self.height_above_takeoff_m,
            self.gimbal_heading_deg,
            self.gimbal_pitch_deg,
        )
    }
}

/// One ground-truth box.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Annotation {
    /// Unique annotation id.
    pub id: u64,
    /// The image it belongs to.
    pub image_id: u64,
    /// `[x, y, w, h]` (px).
    pub bbox: [f64; 4],
    /// Box area (px^2).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub area: Option<f64>,
    /// Category id.
    pub category_id: u32,
    /// Identity across frames, when the file is for tracking.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub track_id: Option<u64>,
}

/// A category.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Category {
    /// Id.
    pub id: u32,
    /// Name.
    pub name: String,
    /// Super-category.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub supercategory: Option<String>,
}

/// A video (sequence) entry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Video {
    /// Id referenced by `images[].video_id`.
    pub id: u64,
    /// Sequence name.
    pub name: String,
}

/// One frame of a sequence, with what the tracker needs to know about it.
#[derive(Debug, Clone, PartialEq)]
pub struct SequenceFrame {
    /// Index into [`Dataset::images`].
    pub image_index: usize,
    /// The image id.
    pub image_id: u64,
    /// 1-based frame number within the sequence (MOTChallenge convention).
    pub frame_number: u64,
    /// Frame number in the original video (`source.frame_no`, else `frame_index`, else the
    /// 1-based position): gaps show frames that were skipped, which the tracker's motion model
    /// must predict across.
    pub video_frame: u64,
    /// Seconds since the sequence's first frame.
    pub time_s: f64,
}

/// The frames of one video, in order.
#[derive(Debug, Clone, PartialEq)]
pub struct Sequence {
    /// Sequence name (folder / video name).
    pub name: String,
    /// Frames in capture order.
    pub frames: Vec<SequenceFrame>,
}

/// Reads and validates a SeaDronesSee JSON file.
pub fn read_dataset(path: &Path) -> Result<Dataset, FormatError> {
    let ds: Dataset = read_json(path)?;
    validate(&ds, path)?;
    Ok(ds)
}

/// Parses and validates SeaDronesSee JSON held in memory, as [`read_dataset`] does a file;
/// `path` only names it in errors.
pub fn from_slice(bytes: &[u8], path: &Path) -> Result<Dataset, FormatError> {
    let ds: Dataset = parse_json(bytes, path)?;
    validate(&ds, path)?;
    Ok(ds)
}

/// [`from_slice`] for text.
pub fn from_str(text: &str, path: &Path) -> Result<Dataset, FormatError> {
    from_slice(text.as_bytes(), path)
}

fn validate(ds: &Dataset, path: &Path) -> Result<(), FormatError> {
    let mut ids = HashMap::with_capacity(ds.images.len());
    for (i, im) in ds.images.iter().enumerate() {
        if let Some(prev) = ids.insert(im.id, i) {
            return Err(FormatError::invalid(
                path,
                format!("images[{i}].id"),
                format!("duplicate image id {} (also images[{prev}])", im.id),
            ));
        }
        if let Some(m) = &im.meta {
            let fields = [
                ("latitude", m.latitude),
                ("longitude", m.longitude),
                ("height_above_takeoff(meter)", m.height_above_takeoff_m),
                ("gimbal_heading(degrees)", m.gimbal_heading_deg),
                ("gimbal_pitch(degrees)", m.gimbal_pitch_deg),
            ];
            for (name, v) in fields {
                if !v.is_finite() {
                    return Err(FormatError::invalid(
                        path,
                        format!("images[{i}].meta.{name}"),
                        "not a finite number",
                    ));
                }
            }
            if !(-90.0..=90.0).contains(&m.latitude) {
                return Err(FormatError::invalid(
                    path,
                    format!("images[{i}].meta.latitude"),
                    format!("latitude {} outside [-90, 90]", m.latitude),
                ));
            }
            // Metadata is interpolated between records: finite values of any size would
            // overflow there (1e308 to -1e308 gives NaN), and are no drone's position anyway.
            if !(-180.0..=180.0).contains(&m.longitude) {
                return Err(FormatError::invalid(
                    path,
                    format!("images[{i}].meta.longitude"),
                    format!("longitude {} outside [-180, 180]", m.longitude),
                ));
            }
            if m.height_above_takeoff_m.abs() > MAX_HEIGHT_M {
                return Err(FormatError::invalid(
                    path,
                    format!("images[{i}].meta.height_above_takeoff(meter)"),
                    format!(
                        "height {} m outside [-{MAX_HEIGHT_M}, {MAX_HEIGHT_M}]",
                        m.height_above_takeoff_m
                    ),
                ));
            }
        }
        if let (Some(vid), Some(videos)) = (im.video_id, &ds.videos) {
            if !videos.iter().any(|v| v.id == vid) {
                return Err(FormatError::invalid(
                    path,
                    format!("images[{i}].video_id"),
                    format!("video id {vid} is not in `videos`"),
                ));
            }
        }
    }
    for (i, a) in ds.annotations.iter().enumerate() {
        if !ids.contains_key(&a.image_id) {
            return Err(FormatError::invalid(
                path,
                format!("annotations[{i}].image_id"),
                format!("no image with id {}", a.image_id),
            ));
        }
        if !a.bbox.iter().all(|v| v.is_finite()) || a.bbox[2] < 0.0 || a.bbox[3] < 0.0 {
            return Err(FormatError::invalid(
                path,
                format!("annotations[{i}].bbox"),
                format!(
                    "box must be finite with non-negative size, got {:?}",
                    a.bbox
                ),
            ));
        }
    }
    Ok(())
}

impl Dataset {
    /// The name of the sequence an image belongs to.
    fn sequence_name(&self, im: &Image) -> String {
        if let (Some(vid), Some(videos)) = (im.video_id, &self.videos) {
            if let Some(v) = videos.iter().find(|v| v.id == vid) {
                return v.name.clone();
            }
        }
        let source = im.source.as_ref();
        source
            .and_then(|s| s.folder_name.clone())
            .or_else(|| {
                source.and_then(|s| s.video.as_ref()).map(|v| {
                    Path::new(v)
                        .file_stem()
                        .map(|s| s.to_string_lossy().into_owned())
                        .unwrap_or_else(|| v.clone())
                })
            })
            .unwrap_or_else(|| "sequence".to_string())
    }

    /// Groups the images into sequences (sorted by name), each in frame order, with frame times
    /// from `date_time` when every frame has one, else from frame numbers at `fps`.
    pub fn sequences(&self, fps: f64) -> Vec<Sequence> {
        let mut groups: BTreeMap<String, Vec<usize>> = BTreeMap::new();
        for (i, im) in self.images.iter().enumerate() {
            groups.entry(self.sequence_name(im)).or_default().push(i);
        }
        groups
            .into_iter()
            .map(|(name, mut idx)| {
                let order = |im: &Image| {
                    im.source
                        .as_ref()
                        .and_then(|s| s.frame_no)
                        .or(im.frame_index)
                        .unwrap_or(im.id)
                };
                idx.sort_by_key(|&i| (order(&self.images[i]), self.images[i].id));
                let stamps: Option<Vec<chrono::NaiveDateTime>> = idx
                    .iter()
                    .map(|&i| self.images[i].date_time.as_deref().and_then(parse_time))
                    .collect();
                let times: Vec<f64> = match stamps {
                    Some(t) if !t.is_empty() && t.windows(2).all(|w| w[1] >= w[0]) => {
                        t.iter().map(|v| seconds_between(&t[0], v)).collect()
                    }
                    _ => {
                        let first = idx.first().map(|&i| order(&self.images[i])).unwrap_or(0);
                        idx.iter()
                            .map(|&i| (order(&self.images[i]).saturating_sub(first)) as f64 / fps)
                            .collect()
                    }
                };
                let frames = idx
                    .iter()
                    .zip(times)
                    .enumerate()
                    .map(|(k, (&i, time_s))| {
                        let im = &self.images[i];
                        SequenceFrame {
                            image_index: i,
                            image_id: im.id,
                            frame_number: k as u64 + 1,
                            video_frame: im
                                .source
                                .as_ref()
                                .and_then(|s| s.frame_no)
                                .or(im.frame_index)
                                .unwrap_or(k as u64 + 1),
                            time_s,
                        }
                    })
                    .collect();
                Sequence { name, frames }
            })
            .collect()
    }
}

impl Dataset {
    /// The camera metadata of every frame of `seq`, treating the images' `meta` as a log: a
    /// record is a new sample when its values change, and it describes the moment `lag_s`
    /// before the first frame it came with. Each frame's metadata is interpolated between the
    /// samples around its time (clamped at the ends); frames without `meta` get `None`.
    ///
    /// SeaDronesSee's DJI logs update at about 1 Hz and lag the video by about 1 s; simulated
    /// metadata changes every frame and has no lag (`lag_s` = 0 then reproduces it exactly).
    pub fn frame_metadata(
        &self,
        seq: &Sequence,
        lag_s: f64,
    ) -> Result<Vec<Option<FrameMetadata>>, GeoError> {
        let mut samples: Vec<(f64, FrameMetadata)> = Vec::new();
        let mut last: Option<&Meta> = None;
        for f in &seq.frames {
            let Some(meta) = self.images[f.image_index].meta.as_ref() else {
                continue;
            };
            if last.is_some_and(|l| same_record(l, meta)) {
                continue;
            }
            last = Some(meta);
            samples.push((f.time_s - lag_s, meta.to_frame_metadata()?));
        }
        Ok(seq
            .frames
            .iter()
            .map(|f| {
                self.images[f.image_index].meta.as_ref()?;
                let after = samples.partition_point(|(t, _)| *t <= f.time_s);
                match (
                    after.checked_sub(1).map(|k| &samples[k]),
                    samples.get(after),
                ) {
                    (Some((t0, m0)), Some((t1, m1))) => {
                        Some(m0.interpolate(m1, (f.time_s - t0) / (t1 - t0)))
                    }
                    (Some((_, m)), None) | (None, Some((_, m))) => Some(*m),
                    (None, None) => None,
                }
            })
            .collect())
    }
}

/// Whether two metadata records carry the same pose (a log record repeated on several frames).
fn same_record(a: &Meta, b: &Meta) -> bool {
    a.latitude == b.latitude
        && a.longitude == b.longitude
        && a.height_above_takeoff_m == b.height_above_takeoff_m
        && a.gimbal_heading_deg == b.gimbal_heading_deg
        && a.gimbal_pitch_deg == b.gimbal_pitch_deg
}

/// Parses an ISO 8601 date-time without zone (`%Y-%m-%dT%H:%M:%S%.f`, or with a space
/// instead of `T`).
fn parse_time(s: &str) -> Option<chrono::NaiveDateTime> {
    chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%dT%H:%M:%S%.f")
        .or_else(|_| chrono::NaiveDateTime::parse_from_str(s, "%Y-%m-%d %H:%M:%S%.f"))
        .ok()
}

/// Seconds from `from` to `to`, exact to the microsecond.
fn seconds_between(from: &chrono::NaiveDateTime, to: &chrono::NaiveDateTime) -> f64 {
    let d = *to - *from;
    d.num_microseconds()
        .map_or(d.num_milliseconds() as f64 * 1e-3, |us| us as f64 * 1e-6)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::io::Write;

    fn write(content: &str) -> tempfile::NamedTempFile {
        let mut f = tempfile::NamedTempFile::new().unwrap();
        f.write_all(content.as_bytes()).unwrap();
        f
    }

    const META: &str = r#""meta": {"latitude": 47.6, "longitude": 9.2, "height_above_takeoff(meter)": 20.0,
        "gimbal_heading(degrees)": 10.0, "gimbal_pitch(degrees)": 45.0}"#;

    #[test]
    fn groups_and_orders_sequences() {
        let f = write(&format!(
            r#"{{"images": [
              {{"id": 7, "width": 100, "height": 50, "source": {{"folder_name": "B", "frame_no": 30}}, {META}}},
              {{"id": 5, "width": 100, "height": 50, "source": {{"folder_name": "A", "frame_no": 60}}}},
              {{"id": 6, "width": 100, "height": 50, "source": {{"folder_name": "A", "frame_no": 15}}}}
            ], "annotations": [{{"id": 1, "image_id": 5, "bbox": [1, 2, 3, 4], "category_id": 1, "track_id": 3}}]}}"#
        ));
        let ds = read_dataset(f.path()).unwrap();
        let seqs = ds.sequences(DEFAULT_VIDEO_FPS);
        assert_eq!(seqs.len(), 2);
        assert_eq!(seqs[0].name, "A");
        assert_eq!(
            seqs[0]
                .frames
                .iter()
                .map(|f| f.image_id)
                .collect::<Vec<_>>(),
            vec![6, 5]
        );
        assert!((seqs[0].frames[1].time_s - 1.5).abs() < 1e-12);
        assert_eq!(seqs[0].frames[1].frame_number, 2);
        assert_eq!(ds.annotations[0].track_id, Some(3));
        assert!(ds.images[0]
            .meta
            .as_ref()
            .unwrap()
            .to_frame_metadata()
            .is_ok());
    }

    #[test]
    fn bad_files_name_the_place() {
        let cases = [
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1}, {"id": 1, "width": 1, "height": 1}]}"#,
                "images[1].id",
            ),
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1}], "annotations": [{"id": 1, "image_id": 2, "bbox": [0,0,1,1], "category_id": 1}]}"#,
                "annotations[0].image_id",
            ),
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1, "meta": {"latitude": "x"}}]}"#,
                "images[0].meta.latitude",
            ),
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1, "meta": {"latitude": 99.0, "longitude": 0.0, "height_above_takeoff(meter)": 1.0, "gimbal_heading(degrees)": 0.0, "gimbal_pitch(degrees)": 0.0}}]}"#,
                "images[0].meta.latitude",
            ),
            (r#"{"images": 3}"#, "images"),
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1, "meta": {"latitude": 9.0, "longitude": 1e308, "height_above_takeoff(meter)": 1.0, "gimbal_heading(degrees)": 0.0, "gimbal_pitch(degrees)": 0.0}}]}"#,
                "images[0].meta.longitude",
            ),
            (
                r#"{"images": [{"id": 1, "width": 1, "height": 1, "meta": {"latitude": 9.0, "longitude": 0.0, "height_above_takeoff(meter)": -1e6, "gimbal_heading(degrees)": 0.0, "gimbal_pitch(degrees)": 0.0}}]}"#,
                "images[0].meta.height_above_takeoff(meter)",
            ),
        ];
        for (content, place) in cases {
            let f = write(content);
            let e = read_dataset(f.path()).unwrap_err().to_string();
            assert!(e.contains(place), "{e} should name {place}");
            // Parsing from memory names the same place and the path it is given (serde_json's
            // slice and reader parsers may count the error's column one apart).
            let from_memory = from_str(content, f.path()).unwrap_err().to_string();
            assert!(
                from_memory.contains(place),
                "{from_memory} should name {place}"
            );
            assert!(from_memory.starts_with(&f.path().display().to_string()));
        }
    }

    #[test]
    fn from_slice_reads_what_read_dataset_reads() {
        let text = format!(
            r#"{{"images": [{{"id": 7, "width": 100, "height": 50, {META}}}],
              "annotations": [{{"id": 1, "image_id": 7, "bbox": [1, 2, 3, 4], "category_id": 1}}]}}"#
        );
        let f = write(&text);
        let from_file = read_dataset(f.path()).unwrap();
        let from_memory = from_slice(text.as_bytes(), Path::new("x.json")).unwrap();
        assert_eq!(from_memory.images, from_file.images);
        assert_eq!(from_memory.annotations, from_file.annotations);
    }

    #[test]
    fn metadata_log_is_interpolated_with_lag() {
        let img = |id: u64, frame: u64, lat: f64| {
            format!(
                r#"{{"id": {id}, "width": 100, "height": 50, "source": {{"folder_name": "A", "frame_no": {frame}}},
                  "meta": {{"latitude": {lat}, "longitude": 9.0, "height_above_takeoff(meter)": 20.0,
                  "gimbal_heading(degrees)": 0.0, "gimbal_pitch(degrees)": 90.0}}}}"#
            )
        };
        // A log that updates every other frame (frames at 1/30 s).
        let f = write(&format!(
            r#"{{"images": [{}, {}, {}, {}]}}"#,
            img(1, 0, 47.0),
            img(2, 1, 47.0),
            img(3, 2, 47.002),
            img(4, 3, 47.002)
        ));
        let ds = read_dataset(f.path()).unwrap();
        let seq = &ds.sequences(30.0)[0];
        assert_eq!(seq.frames[3].video_frame, 3);
        let no_lag = ds.frame_metadata(seq, 0.0).unwrap();
        let lat: Vec<f64> = no_lag.iter().map(|m| m.unwrap().position.lat_deg).collect();
        assert!((lat[1] - 47.001).abs() < 1e-9, "{lat:?}");
        assert!((lat[3] - 47.002).abs() < 1e-9);
        // With a lag of one frame the second record already holds at frame 1.
        let lagged = ds.frame_metadata(seq, 1.0 / 30.0).unwrap();
        assert!((lagged[1].unwrap().position.lat_deg - 47.002).abs() < 1e-9);
    }

    #[test]
    fn parses_date_times() {
        let a = parse_time("2020-08-25T14:19:21.647133").unwrap();
        let b = parse_time("2020-08-25 14:19:22.147633").unwrap();
        assert_eq!(seconds_between(&a, &b), 0.5005);
        assert!(parse_time("yesterday").is_none());
    }

    #[test]
    fn reads_the_real_validation_subset() {
        let path = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../shared/data/seadronessee/val_subset_annotations.json"
        ));
        assert!(
            path.exists(),
            "fixture missing: {} (../shared must sit beside the repo)",
            path.display()
        );
        let ds = read_dataset(path).unwrap();
        let seqs = ds.sequences(DEFAULT_VIDEO_FPS);
        assert_eq!(seqs.len(), 3);
        assert!(seqs.iter().all(|s| s.frames.len() == 60));
        // 2 Hz sampling: about 0.5 s between frames, from the date_time stamps.
        let dt = seqs[0].frames[1].time_s - seqs[0].frames[0].time_s;
        assert!((dt - 0.5).abs() < 0.01, "{dt}");
    }
}
