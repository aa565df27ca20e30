//! Geolocation on real SeaDronesSee frames: the physical size of swimmers computed from box
//! size x range / focal length should be consistent when the metadata is read correctly.

use mgmot::formats::seadronessee::{read_dataset, DEFAULT_VIDEO_FPS};
use mgmot::geo::{CameraModel, FrameMetadata, Geolocator, Pixel, PoseNoise};
use std::path::Path;

const ANNOTATIONS: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../shared/data/seadronessee/val_subset_annotations.json"
);
const SWIMMER: u32 = 1;
const FOV_DEG: f64 = 70.0;

/// (IQR / median) of the swimmers' physical sizes, and how many were measured, when the
/// gimbal pitch is read with `pitch_reading` (degrees below the horizon from the raw value).
fn swimmer_size_dispersion(pitch_reading: impl Fn(f64) -> f64) -> Vec<(String, f64, f64, usize)> {
    let path = Path::new(ANNOTATIONS);
    assert!(
        path.exists(),
        "fixture missing: {ANNOTATIONS} (../shared must sit beside the repo)"
    );
    let ds = read_dataset(path).unwrap();
    let mut out = Vec::new();
    for seq in ds.sequences(DEFAULT_VIDEO_FPS) {
        let mut sizes = Vec::new();
        for f in &seq.frames {
            let image = &ds.images[f.image_index];
            let m = image.meta.as_ref().unwrap();
            let cam = CameraModel::from_hfov(image.width, image.height, FOV_DEG).unwrap();
            let fm = FrameMetadata::from_seadronessee(
                m.latitude,
                m.longitude,
                m.height_above_takeoff_m,
                m.gimbal_heading_deg,
                pitch_reading(m.gimbal_pitch_deg),
            )
            .unwrap();
            let g = Geolocator::new(fm.nadir_on_water(), cam, PoseNoise::default());
            let frame = g.frame(&fm).unwrap();
            for a in ds
                .annotations
                .iter()
                .filter(|a| a.image_id == image.id && a.category_id == SWIMMER)
            {
                let [x, y, w, h] = a.bbox;
                if let Ok(loc) = frame.locate(Pixel::new(x + w / 2.0, y + h / 2.0)) {
                    sizes.push((w * h).sqrt() * loc.range_m / cam.intrinsics.fx);
                }
            }
        }
        sizes.sort_by(f64::total_cmp);
        let q = |p: f64| sizes[((sizes.len() - 1) as f64 * p).round() as usize];
        let median = q(0.5);
        out.push((
            seq.name.clone(),
            (q(0.75) - q(0.25)) / median,
            median,
            sizes.len(),
        ));
    }
    out
}

#[test]
fn swimmer_sizes_are_consistent_with_the_dataset_reading_of_the_metadata() {
    let dataset_reading = swimmer_size_dispersion(|p| p);
    let from_nadir_reading = swimmer_size_dispersion(|p| 90.0 - p);
    for ((name, iqr, median, n), (_, alt_iqr, _, alt_n)) in
        dataset_reading.iter().zip(&from_nadir_reading)
    {
        println!(
            "{name}: {n} swimmers, median size {median:.2} m, IQR/median {iqr:.3} \
             (pitch read from nadir instead: {alt_iqr:.3} over {alt_n})"
        );
        assert!(*n > 20, "{name}: too few swimmers geolocated ({n})");
        // A swimmer (head and shoulders, or a lifejacket) is a few decimetres to about a metre.
        assert!(
            (0.1..2.0).contains(median),
            "{name}: implausible median size {median} m"
        );
    }
    let mean =
        |v: &[(String, f64, f64, usize)]| v.iter().map(|r| r.1).sum::<f64>() / v.len() as f64;
    let (ours, alt) = (mean(&dataset_reading), mean(&from_nadir_reading));
    println!("mean IQR/median: dataset reading {ours:.3}, from-nadir reading {alt:.3}");
    assert!(
        ours < alt,
        "dataset reading should be more consistent: {ours} vs {alt}"
    );
    assert!(ours < 0.6, "sizes too dispersed: {ours}");
}
