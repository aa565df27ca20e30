//! MOTChallenge txt: `mot::parse_str`, and `write` -> `parse_str` of what it accepted.

use mgmot::formats::mot::{parse_str, write, MotRecord};
use std::path::Path;

/// `data` as the text of a MOT file (invalid UTF-8 is what `read_file` refuses before
/// parsing, so only text is parsed). Accepted records are finite, with whole frame numbers
/// >= 1 and whole ids, and survive `write` -> `parse_str`.
pub fn txt(data: &[u8]) {
    let Ok(text) = std::str::from_utf8(data) else {
        return;
    };
    let path = Path::new("fuzz.txt");
    let Ok(records) = parse_str(text, path) else {
        return;
    };
    for r in &records {
        check(r);
        let gt = r.to_gt_annotation();
        assert_eq!(gt.considered, r.conf != 0.0);
        assert!(r.to_pred_annotation().considered);
    }
    let mut out = Vec::new();
    write(&mut out, &records).expect("writing to a Vec cannot fail");
    let text = String::from_utf8(out).expect("write produces UTF-8");
    let again = parse_str(&text, path)
        .unwrap_or_else(|e| panic!("written records do not parse back: {e}\n{text}"));
    // `write` spells a missing visibility as -1 and writes no signature column.
    let expected: Vec<MotRecord> = records
        .iter()
        .map(|r| MotRecord {
            visibility: Some(r.visibility.unwrap_or(-1.0)),
            appearance: None,
            ..*r
        })
        .collect();
    assert_eq!(again, expected, "{text}");
}

fn check(r: &MotRecord) {
    let b = r.bbox;
    assert!(r.frame >= 1 && r.frame <= u64::from(u32::MAX), "{r:?}");
    assert!(r.id.unsigned_abs() <= i32::MAX as u64, "{r:?}");
    assert!(
        [b.x, b.y, b.w, b.h, r.conf].iter().all(|v| v.is_finite()),
        "{r:?}"
    );
    assert!(r.visibility.is_none_or(f64::is_finite), "{r:?}");
}
