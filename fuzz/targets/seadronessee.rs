//! SeaDronesSee JSON: `seadronessee::from_slice` (what `read_dataset` does to a file's
//! bytes), then what `mgmot track` and `mgmot geolocate` do with a dataset that validated:
//! sequences, frame times, interpolated frame metadata.

use super::{geodetic_ok, unit_quaternion_ok};
use mgmot::formats::seadronessee::{from_slice, DEFAULT_VIDEO_FPS};
use std::path::Path;

/// `data` as the bytes of a SeaDronesSee JSON file.
pub fn json(data: &[u8]) {
    let Ok(ds) = from_slice(data, Path::new("fuzz.json")) else {
        return;
    };
    for im in &ds.images {
        if let Some(meta) = &im.meta {
            if let Ok(m) = meta.to_frame_metadata() {
                check_metadata(&m);
            }
        }
    }
    let sequences = ds.sequences(DEFAULT_VIDEO_FPS);
    let n: usize = sequences.iter().map(|s| s.frames.len()).sum();
    assert_eq!(n, ds.images.len(), "every image is in one sequence");
    for seq in &sequences {
        let mut previous = f64::NEG_INFINITY;
        for (k, f) in seq.frames.iter().enumerate() {
            assert!(f.time_s.is_finite() && f.time_s >= 0.0, "{f:?}");
            assert!(f.time_s >= previous, "frame times go back: {seq:?}");
            previous = f.time_s;
            assert_eq!(f.frame_number, k as u64 + 1);
            assert_eq!(ds.images[f.image_index].id, f.image_id);
        }
        // `mgmot track --metadata-lag-s`: none (simulator) and SeaDronesSee's 1 s.
        for lag_s in [0.0, 1.0] {
            let Ok(metadata) = ds.frame_metadata(seq, lag_s) else {
                continue;
            };
            assert_eq!(metadata.len(), seq.frames.len());
            for (f, m) in seq.frames.iter().zip(&metadata) {
                assert_eq!(m.is_some(), ds.images[f.image_index].meta.is_some());
                if let Some(m) = m {
                    check_metadata(m);
                }
            }
        }
    }
}

/// Frame metadata reaches the geolocation and the tracker: it must be finite.
fn check_metadata(m: &mgmot::geo::FrameMetadata) {
    assert!(geodetic_ok(&m.position), "{m:?}");
    assert!(m.height_above_sea_m.is_finite(), "{m:?}");
    assert!(unit_quaternion_ok(&m.camera_attitude), "{m:?}");
}
