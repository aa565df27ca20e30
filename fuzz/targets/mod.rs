//! The fuzz targets' bodies, one function per decoder that takes outside input.
//!
//! This module is compiled twice, from this one source: by the cargo-fuzz crate
//! (`fuzz/src/lib.rs`, driven by libFuzzer on nightly or `RUSTC_BOOTSTRAP=1`) and by the
//! stable harness `tests/fuzz_decoders.rs` (part of the normal `cargo test`), both with
//! `#[path]`. It uses only `mgmot`'s public API and crates `mgmot` itself depends on, so the
//! library carries no fuzzing code or feature.
//!
//! Every target takes arbitrary bytes and panics (through `assert!`) only when a property
//! fails: the decoders never panic; framing and MAVLink survive encode -> decode; numbers a
//! decoder hands on as valid (positions, attitudes, frame metadata, sequence times) are finite.

// Each consumer uses its own subset of the helpers.
#![allow(dead_code)]

pub mod config;
pub mod mavlink;
pub mod mot;
pub mod seadronessee;
pub mod sim_framing;

/// One target: its name (the cargo-fuzz binary, `fuzz/corpus/<name>/`, `fuzz/dict/<name>.dict`)
/// and its body, which must not panic on any input.
pub type Target = (&'static str, fn(&[u8]));

/// Every target.
pub const ALL: &[Target] = &[
    ("mavlink_frames", mavlink::frames),
    ("mavlink_messages", mavlink::messages),
    ("sim_framing", sim_framing::stream),
    ("seadronessee_json", seadronessee::json),
    ("mot_txt", mot::txt),
    ("runtime_config", config::toml),
];

/// Reads structured values off the front of a fuzz input; past its end every read gives
/// zeros, so every input means something.
pub struct Input<'a> {
    data: &'a [u8],
}

impl<'a> Input<'a> {
    /// Reads from `data`.
    pub fn new(data: &'a [u8]) -> Self {
        Self { data }
    }

    /// Up to `n` bytes (fewer at the end).
    pub fn bytes(&mut self, n: usize) -> &'a [u8] {
        let (head, tail) = self.data.split_at(n.min(self.data.len()));
        self.data = tail;
        head
    }

    /// The rest of the input.
    pub fn rest(&mut self) -> &'a [u8] {
        self.bytes(self.data.len())
    }

    fn array<const N: usize>(&mut self) -> [u8; N] {
        let mut out = [0u8; N];
        let b = self.bytes(N);
        out[..b.len()].copy_from_slice(b);
        out
    }

    /// A byte.
    pub fn u8(&mut self) -> u8 {
        self.array::<1>()[0]
    }

    /// A little-endian u32.
    pub fn u32(&mut self) -> u32 {
        u32::from_le_bytes(self.array())
    }

    /// A little-endian u64.
    pub fn u64(&mut self) -> u64 {
        u64::from_le_bytes(self.array())
    }

    /// A boolean (lowest bit of a byte).
    pub fn bool(&mut self) -> bool {
        self.u8() & 1 == 1
    }
}

/// Whether every component of a quaternion is finite and it has unit length.
pub fn unit_quaternion_ok(q: &nalgebra::UnitQuaternion<f64>) -> bool {
    q.coords.iter().all(|v| v.is_finite()) && (q.norm() - 1.0).abs() < 1e-6
}

/// Whether a position is finite, with a latitude in [-90, 90].
pub fn geodetic_ok(g: &mgmot::geo::Geodetic) -> bool {
    g.lat_deg.is_finite()
        && g.lon_deg.is_finite()
        && g.alt_m.is_finite()
        && (-90.0..=90.0).contains(&g.lat_deg)
}
