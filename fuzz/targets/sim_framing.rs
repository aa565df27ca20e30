//! The simulator's frame stream: `FrameHeader::decode`, `rgb24_len` and the runtime's stream
//! reader `read_sim_frame` on arbitrary bytes, and header encode -> decode.

use super::Input;
use mgmot::camera::sim_framing::{
    is_end_of_stream, FrameHeader, FOURCC_RGB3, HEADER_LEN, MAX_PAYLOAD,
};
use mgmot::camera::{read_sim_frame, CaptureTime};
use mgmot::telemetry::AutopilotTimeUs;
use std::path::Path;

/// At most this many frames are read from one input (each takes at least a header's bytes,
/// so the bound is never reached; it keeps a reader that stopped consuming from looping).
const MAX_FRAMES: usize = 1 << 16;

/// `data` as the bytes of the socket: the header decoder on its start, then the stream reader
/// frame by frame to its end or first error; then a header built from its first bytes'
/// fields through encode -> decode.
pub fn stream(data: &[u8]) {
    // The header decoder on the raw bytes: what it accepts encodes back to the same bytes.
    if let Ok(h) = FrameHeader::decode(data) {
        assert_eq!(&h.encode()[..], &data[..HEADER_LEN]);
        check_rgb24_len(&h);
    }

    // The stream reader: every frame it returns is a well-formed RGB24 frame whose header and
    // pixels, written again, are the bytes it consumed.
    let mut rest = data;
    for _ in 0..MAX_FRAMES {
        let before = rest;
        match read_sim_frame(&mut rest, Path::new("fuzz.sock")) {
            Ok(Some(f)) => {
                let expected = u128::from(f.width_px) * u128::from(f.height_px) * 3;
                assert_eq!(f.rgb.len() as u128, expected);
                assert!(!f.rgb.is_empty() && f.rgb.len() <= MAX_PAYLOAD);
                let CaptureTime::Autopilot(AutopilotTimeUs(t_us)) = f.captured else {
                    panic!("a simulator frame stamped {:?}", f.captured);
                };
                let consumed = &before[..before.len() - rest.len()];
                let header = FrameHeader::rgb24(f.index, t_us, f.width_px, f.height_px);
                assert_eq!(&consumed[..HEADER_LEN], &header.encode()[..]);
                assert_eq!(&consumed[HEADER_LEN..], &f.rgb[..]);
            }
            Ok(None) => {
                // Only the end-of-stream header ends the stream; it was consumed whole.
                let consumed = &before[..before.len() - rest.len()];
                assert_eq!(consumed.len(), HEADER_LEN);
                assert!(
                    is_end_of_stream(consumed),
                    "end of stream without its header"
                );
                break;
            }
            Err(_) => break,
        }
    }

    // Encode -> decode of a header with arbitrary fields.
    let mut input = Input::new(data);
    let h = FrameHeader {
        index: input.u64(),
        capture_time_us: input.u64(),
        width: input.u32(),
        height: input.u32(),
        fourcc: input.u32().to_le_bytes(),
        payload_len: input.u32(),
    };
    assert_eq!(FrameHeader::decode(&h.encode()), Ok(h));
    check_rgb24_len(&h);
    let rgb = FrameHeader::rgb24(h.index, h.capture_time_us, h.width, h.height);
    assert_eq!(FrameHeader::decode(&rgb.encode()), Ok(rgb));
    check_rgb24_len(&rgb);
}

/// `rgb24_len` accepts exactly the RGB3 headers whose length is `width * height * 3`, in
/// `1..=MAX_PAYLOAD`.
fn check_rgb24_len(h: &FrameHeader) {
    let expected = u128::from(h.width) * u128::from(h.height) * 3;
    let ok = h.fourcc == FOURCC_RGB3
        && u128::from(h.payload_len) == expected
        && expected > 0
        && expected <= MAX_PAYLOAD as u128;
    match h.rgb24_len() {
        Ok(len) => {
            assert!(ok, "{h:?} accepted");
            assert_eq!(len as u128, expected);
        }
        Err(_) => assert!(!ok, "{h:?} refused"),
    }
}
