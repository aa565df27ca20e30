//! MAVLink 2 signing (<https://mavlink.io/en/guide/message_signing.html>) as mgmot uses it.
//!
//! With a key configured, every message mgmot sends is signed by [`Signer`] (the link id from
//! the configuration; the timestamp is the spec's: 10 µs units since 2015-01-01 UTC, strictly
//! increasing). Incoming frames:
//!
//! - signed frames are verified by [`Signer::check`]: the signature, per-stream replay
//!   protection (link id, system, component), and two bounds `mavlink_core`'s own verifier
//!   lacks: a frame stamped more than [`MAX_FORWARD_SKEW`] ahead of our clock is refused (a
//!   peer cannot push our clock, and so our outgoing timestamps, forward), and the stream
//!   timestamps and our own last timestamp are persisted ([`Signer::persist`], synced to disk;
//!   the link persists them before a signed command is handed on) so that a signed frame
//!   captured before a restart, even a SIGKILL right after the command, cannot be replayed
//!   after it;
//! - unsigned frames are let through, marked, so that telemetry from an autopilot or router
//!   that does not sign still feeds the geolocation; commands that were not signed are refused
//!   (COMMAND_ACK MAV_RESULT_DENIED) and not carried out.
//!
//! ArduPilot and PX4 drop unsigned packets silently when signing is on. mgmot answers DENIED
//! instead: it is a component behind the autopilot or a router, and a GCS that forgot to sign
//! sees at once why its tracking command did nothing, rather than retrying into a timeout. The
//! answer carries nothing secret and goes only to the sender named in the frame.

use super::dialect::MavMessage;
use mavlink_core::error::ParserError;
use mavlink_core::{MAVLinkMessageRaw, MAVLinkV2MessageRaw, MavHeader, Message, SigningConfig};
use std::collections::HashMap;
use std::path::{Path, PathBuf};

/// How far ahead of our clock a signed frame may be stamped (10 µs units: 60 s). The spec
/// lets a receiver's clock follow the newest timestamp it has seen; bounding that keeps one
/// frame stamped far in the future (or near the 48-bit wrap) from stopping later, correctly
/// timed streams and from dragging mgmot's own signatures with it.
pub const MAX_FORWARD_SKEW: u64 = 60 * 100_000;

/// How far behind our clock a new stream's first frame may be (10 µs units: 60 s, the spec's
/// "one minute").
pub const MAX_NEW_STREAM_AGE: u64 = 60 * 100_000;

/// The signing timestamp's epoch, 2015-01-01T00:00:00Z, in Unix seconds.
const SIGNING_EPOCH_UNIX_S: u64 = 1_420_070_400;

/// Wall clocks before this (2024-01-01, in signing units) are taken as unset: a companion board
/// without a real-time clock starts in 1970 until NTP or GPS time arrives.
const PLAUSIBLE_CLOCK: u64 = (1_704_067_200 - SIGNING_EPOCH_UNIX_S) * 100_000;

/// The signing timestamp's largest value (48 bits).
const TIMESTAMP_MAX: u64 = (1 << 48) - 1;

/// Why a signed frame was refused (unsigned frames are not judged here).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Refusal {
    /// The signature does not match the key.
    BadSignature,
    /// The timestamp is not newer than the last one of its stream: a replay.
    Replayed,
    /// The timestamp is more than [`MAX_FORWARD_SKEW`] ahead of our clock.
    TooFarAhead,
    /// A new stream whose first timestamp is more than [`MAX_NEW_STREAM_AGE`] old.
    TooOld,
}

/// Could not read or write the persisted signing state.
#[derive(Debug, thiserror::Error)]
#[error("signing state file {path}: {reason}")]
pub struct SigningStateError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub reason: String,
}

/// The persisted part of the signing state.
#[derive(Debug, Default, serde::Serialize, serde::Deserialize)]
struct Persisted {
    /// The last timestamp mgmot signed with.
    last_sent: u64,
    /// The newest accepted timestamp per stream: (link id, system, component, timestamp).
    streams: Vec<(u8, u32, u8, u64)>,
}

/// Signs outgoing frames and verifies incoming ones with one key, keeping the timestamps
/// (see the module documentation).
#[derive(Debug)]
pub struct Signer {
    key: [u8; 32],
    link_id: u8,
    last_sent: u64,
    streams: HashMap<(u8, u32, u8), u64>,
    state_file: Option<PathBuf>,
    dirty: bool,
}

impl Signer {
    /// A signer for `key`, putting `link_id` in our signatures. With `state_file`, the state a
    /// previous run persisted there is loaded (a missing file is a first start); a file that
    /// exists but cannot be read or parsed is an error, not silently a fresh start.
    pub fn new(
        key: [u8; 32],
        link_id: u8,
        state_file: Option<&Path>,
    ) -> Result<Self, SigningStateError> {
        let mut signer = Signer {
            key,
            link_id,
            last_sent: 0,
            streams: HashMap::new(),
            state_file: state_file.map(Path::to_path_buf),
            dirty: false,
        };
        if let Some(path) = state_file {
            let err = |reason: String| SigningStateError {
                path: path.to_path_buf(),
                reason,
            };
            match std::fs::read(path) {
                Ok(bytes) => {
                    let p: Persisted = serde_json::from_slice(&bytes)
                        .map_err(|e| err(format!("not a signing state ({e})")))?;
                    signer.last_sent = p.last_sent.min(TIMESTAMP_MAX);
                    for (link, system, component, ts) in p.streams {
                        signer.streams.insert((link, system, component), ts);
                    }
                }
                Err(e) if e.kind() == std::io::ErrorKind::NotFound => {}
                Err(e) => return Err(err(e.to_string())),
            }
            if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
                std::fs::create_dir_all(dir)
                    .map_err(|e| err(format!("cannot create {}: {e}", dir.display())))?;
            }
            // Fail at start-up, not at the first persist, when the file cannot be written.
            signer.persist()?;
        }
        Ok(signer)
    }

    /// Our clock in signing units: the wall clock, never behind what we already signed with or
    /// accepted before a restart.
    fn reference(&self, wall: u64) -> u64 {
        let floor = self
            .streams
            .values()
            .copied()
            .max()
            .unwrap_or(0)
            .max(self.last_sent);
        if wall < PLAUSIBLE_CLOCK {
            // No usable wall clock: the persisted floor is the best we have.
            floor
        } else {
            wall.max(self.last_sent)
        }
    }

    /// Judges a signed frame at wall-clock time `wall` (signing units, [`signing_now`]);
    /// an accepted frame's timestamp becomes its stream's newest.
    pub fn check_at(&mut self, raw: &MAVLinkV2MessageRaw, wall: u64) -> Result<(), Refusal> {
        let mut signature = [0u8; mavlink_core::consts::v2::SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(&self.key, &mut signature);
        if signature != raw.signature_value() {
            return Err(Refusal::BadSignature);
        }
        let ts = raw.signature_timestamp();
        let stream = (raw.signature_link_id(), raw.system_id(), raw.component_id());
        let reference = self.reference(wall);
        // With no plausible wall clock and nothing persisted, the first valid frame sets it.
        if reference > 0 && ts > reference.saturating_add(MAX_FORWARD_SKEW) {
            return Err(Refusal::TooFarAhead);
        }
        match self.streams.get(&stream) {
            Some(&last) if ts <= last => return Err(Refusal::Replayed),
            Some(_) => {}
            None if ts.saturating_add(MAX_NEW_STREAM_AGE) < reference => {
                return Err(Refusal::TooOld)
            }
            None => {}
        }
        self.streams.insert(stream, ts);
        self.dirty = true;
        Ok(())
    }

    /// [`Signer::check_at`] now.
    pub fn check(&mut self, raw: &MAVLinkV2MessageRaw) -> Result<(), Refusal> {
        self.check_at(raw, signing_now())
    }

    /// The timestamp for our next frame at wall-clock time `wall`: strictly increasing, never
    /// behind the wall clock, and never pushed ahead by peers.
    pub fn next_timestamp_at(&mut self, wall: u64) -> u64 {
        let reference = self.reference(wall);
        let ts = reference.max(self.last_sent + 1).min(TIMESTAMP_MAX);
        self.last_sent = ts;
        self.dirty = true;
        ts
    }

    /// Signs `raw` (a MAVLink 2 frame serialised with the signed flag set) now.
    pub fn sign(&mut self, raw: &mut MAVLinkV2MessageRaw) {
        let ts = self.next_timestamp_at(signing_now());
        raw.signature_timestamp_bytes_mut().copy_from_slice(
            &ts.to_le_bytes()[..mavlink_core::consts::v2::SIGNATURE_TIMESTAMP_SIZE],
        );
        *raw.signature_link_id_mut() = self.link_id;
        let mut signature = [0u8; mavlink_core::consts::v2::SIGNATURE_VALUE_SIZE];
        raw.calculate_signature(&self.key, &mut signature);
        raw.signature_value_mut().copy_from_slice(&signature);
    }

    /// Whether something changed since the last [`Signer::persist`].
    pub fn is_dirty(&self) -> bool {
        self.dirty
    }

    /// Writes the state file (atomically: a temporary file, synced, renamed over it, and the
    /// folder synced), if one is configured: once this returns, the state survives a SIGKILL or
    /// a power cut.
    pub fn persist(&mut self) -> Result<(), SigningStateError> {
        let Some(path) = &self.state_file else {
            return Ok(());
        };
        let err = |reason: String| SigningStateError {
            path: path.clone(),
            reason,
        };
        let state = Persisted {
            last_sent: self.last_sent,
            streams: self
                .streams
                .iter()
                .map(|(&(l, s, c), &t)| (l, s, c, t))
                .collect(),
        };
        let bytes = serde_json::to_vec(&state).map_err(|e| err(e.to_string()))?;
        let mut tmp = path.clone().into_os_string();
        tmp.push(".tmp");
        let tmp = PathBuf::from(tmp);
        let write = || -> std::io::Result<()> {
            use std::io::Write;
            let mut file = std::fs::File::create(&tmp)?;
            file.write_all(&bytes)?;
            file.sync_all()
        };
        write().map_err(|e| err(format!("{}: {e}", tmp.display())))?;
        std::fs::rename(&tmp, path).map_err(|e| err(e.to_string()))?;
        // The rename itself is durable once the folder is synced.
        let dir = path
            .parent()
            .filter(|d| !d.as_os_str().is_empty())
            .unwrap_or(Path::new("."));
        std::fs::File::open(dir)
            .and_then(|d| d.sync_all())
            .map_err(|e| err(format!("{}: {e}", dir.display())))?;
        self.dirty = false;
        Ok(())
    }
}

/// The wall clock in signing units (10 µs since 2015-01-01 UTC); 0 when the clock is before
/// the epoch.
pub fn signing_now() -> u64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map(|d| {
            let since_epoch = d.as_micros() / 10;
            let epoch = u128::from(SIGNING_EPOCH_UNIX_S) * 100_000;
            u64::try_from(since_epoch.saturating_sub(epoch)).unwrap_or(u64::MAX)
        })
        .unwrap_or(0)
        .min(TIMESTAMP_MAX)
}

/// The connection's signing configuration for `key`: sign everything sent with `link_id`,
/// verify signed frames, pass unsigned ones on (to be sorted by [`is_signed`]).
pub fn signing_config(key: [u8; 32], link_id: u8) -> SigningConfig {
    SigningConfig::new(key, link_id, true, true)
}

/// Whether a received frame carried a signature. On a connection set up with
/// [`signing_config`], a signed frame that arrives has passed verification.
pub fn is_signed(raw: &MAVLinkMessageRaw) -> bool {
    match raw {
        MAVLinkMessageRaw::V1(_) => false,
        MAVLinkMessageRaw::V2(m) => {
            m.incompatibility_flags() & mavlink_core::consts::v2::IFLAG_SIGNED != 0
        }
    }
}

/// The header and message of a received frame.
pub fn parse_raw(raw: &MAVLinkMessageRaw) -> Result<(MavHeader, MavMessage), ParserError> {
    let message = MavMessage::parse(raw.version(), raw.message_id(), raw.payload())?;
    let header = MavHeader {
        system_id: raw.system_id(),
        component_id: raw.component_id(),
        sequence: raw.sequence(),
    };
    Ok((header, message))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mavlink::dialect::{MavCmd, COMMAND_LONG_DATA, HEARTBEAT_DATA};
    use mavlink_core::{MavlinkReader, MavlinkVersion, SigningData};

    const KEY: [u8; 32] = [7; 32];

    fn frame(signing: Option<&SigningData>, system_id: u32, m: &MavMessage) -> Vec<u8> {
        let mut buf = Vec::new();
        let header = MavHeader {
            system_id,
            component_id: 190,
            sequence: 0,
        };
        mavlink_core::write_versioned_msg_signed(&mut buf, MavlinkVersion::V2, header, m, signing)
            .unwrap();
        buf
    }

    fn command() -> MavMessage {
        MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            target_system: 1,
            target_component: 191,
            command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
            ..Default::default()
        })
    }

    /// Reads every frame of `bytes` the way the runtime's connection does.
    fn receive(bytes: &[u8]) -> Vec<(bool, MavHeader, MavMessage)> {
        let ours = SigningData::from_config(signing_config(KEY, 0));
        let mut reader = MavlinkReader::new(bytes);
        let mut out = Vec::new();
        while let Ok(raw) =
            reader.read_raw_message_signed::<MavMessage>(MavlinkVersion::V2, Some(&ours))
        {
            let (h, m) = parse_raw(&raw).unwrap();
            out.push((is_signed(&raw), h, m));
        }
        out
    }

    #[test]
    fn signed_frames_are_verified_and_unsigned_ones_pass_marked() {
        let good = SigningData::from_config(SigningConfig::new(KEY, 3, true, false));
        let wrong_key = SigningData::from_config(SigningConfig::new([8; 32], 3, true, false));
        let heartbeat = MavMessage::HEARTBEAT(HEARTBEAT_DATA::default());
        let mut bytes = frame(None, 1, &heartbeat);
        bytes.extend(frame(Some(&good), 255, &command()));
        bytes.extend(frame(Some(&wrong_key), 254, &command()));
        bytes.extend(frame(None, 253, &command()));
        let got: Vec<(bool, u32)> = receive(&bytes)
            .into_iter()
            .map(|(signed, h, _)| (signed, h.system_id))
            .collect();
        // The forged command (wrong key) is dropped; the unsigned ones arrive, marked.
        assert_eq!(got, [(false, 1), (true, 255), (false, 253)]);
    }

    #[test]
    fn a_replayed_signed_frame_is_dropped() {
        let gcs = SigningData::from_config(SigningConfig::new(KEY, 0, true, false));
        let once = frame(Some(&gcs), 255, &command());
        let mut twice = once.clone();
        twice.extend(&once);
        assert_eq!(receive(&twice).len(), 1);
    }

    #[test]
    fn outgoing_frames_are_signed_with_our_link_id() {
        let ours = SigningData::from_config(signing_config(KEY, 9));
        let bytes = frame(Some(&ours), 1, &command());
        let mut reader = MavlinkReader::new(&bytes[..]);
        let raw = reader
            .read_raw_message::<MavMessage>(MavlinkVersion::V2)
            .unwrap();
        assert!(is_signed(&raw));
        let MAVLinkMessageRaw::V2(v2) = raw else {
            panic!("not MAVLink 2")
        };
        assert_eq!(v2.signature_link_id(), 9);
    }

    fn signed_raw(key: [u8; 32], link: u8, system: u32, ts: u64) -> MAVLinkV2MessageRaw {
        let mut raw = MAVLinkV2MessageRaw::new();
        let header = MavHeader {
            system_id: system,
            component_id: 1,
            sequence: 0,
        };
        raw.serialize_message_for_signing(
            header,
            &MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()),
        );
        raw.signature_timestamp_bytes_mut()
            .copy_from_slice(&ts.to_le_bytes()[..6]);
        *raw.signature_link_id_mut() = link;
        let mut sig = [0u8; 6];
        raw.calculate_signature(&key, &mut sig);
        raw.signature_value_mut().copy_from_slice(&sig);
        raw
    }

    /// 2026-01-01 in signing units: a plausible wall clock.
    const WALL: u64 = (1_767_225_600 - SIGNING_EPOCH_UNIX_S) * 100_000;

    #[test]
    fn a_peer_cannot_push_our_clock_forward() {
        let mut s = Signer::new(KEY, 2, None).unwrap();
        let ahead = signed_raw(KEY, 0, 1, WALL + 120 * 100_000);
        assert_eq!(s.check_at(&ahead, WALL), Err(Refusal::TooFarAhead));
        let wrapped = signed_raw(KEY, 0, 1, (1 << 48) - 2);
        assert_eq!(s.check_at(&wrapped, WALL), Err(Refusal::TooFarAhead));
        // Correctly timed frames still pass; ours stay on our clock.
        assert_eq!(s.check_at(&signed_raw(KEY, 0, 1, WALL + 5), WALL), Ok(()));
        assert_eq!(s.check_at(&signed_raw(KEY, 0, 1, WALL + 6), WALL), Ok(()));
        let ours = s.next_timestamp_at(WALL);
        assert!((WALL..WALL + 10).contains(&ours), "{ours}");
        assert!(s.next_timestamp_at(WALL) > ours, "strictly increasing");
    }

    #[test]
    fn replays_bad_keys_and_stale_new_streams_are_refused() {
        let mut s = Signer::new(KEY, 0, None).unwrap();
        assert_eq!(s.check_at(&signed_raw(KEY, 0, 9, WALL), WALL), Ok(()));
        assert_eq!(
            s.check_at(&signed_raw(KEY, 0, 9, WALL), WALL),
            Err(Refusal::Replayed)
        );
        assert_eq!(
            s.check_at(&signed_raw([1; 32], 0, 8, WALL), WALL),
            Err(Refusal::BadSignature)
        );
        assert_eq!(
            s.check_at(&signed_raw(KEY, 0, 7, WALL - 61 * 100_000), WALL),
            Err(Refusal::TooOld)
        );
    }

    #[test]
    fn the_state_survives_a_restart() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("sub").join("signing.json");
        let captured = signed_raw(KEY, 1, 255, WALL + 10);
        let mut s = Signer::new(KEY, 0, Some(&path)).unwrap();
        assert_eq!(s.check_at(&captured, WALL), Ok(()));
        let sent = s.next_timestamp_at(WALL + 50);
        s.persist().unwrap();
        drop(s);
        let mut s = Signer::new(KEY, 0, Some(&path)).unwrap();
        assert_eq!(s.check_at(&captured, WALL + 700), Err(Refusal::Replayed));
        // Our own timestamps never go back across a restart, even with the clock behind.
        assert!(s.next_timestamp_at(WALL) > sent);
        // A corrupt state file is an error, not a silent fresh start.
        std::fs::write(&path, b"not json").unwrap();
        assert!(Signer::new(KEY, 0, Some(&path)).is_err());
    }

    #[test]
    fn signing_now_is_after_2024() {
        assert!(signing_now() > PLAUSIBLE_CLOCK);
    }
}
