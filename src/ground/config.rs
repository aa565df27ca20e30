//! `mgmot ground`'s configuration: where the MAVLink comes from, how to fuse, what to serve.
//! Every key has a default; `mgmot ground` runs without a file.

use crate::config::{ConfigError, CotConfig, CotSettings, Problems};
use mgmot_core::fuse::FuseParams;
use serde::{Deserialize, Serialize};
use std::net::SocketAddr;
use std::path::{Path, PathBuf};
use std::time::Duration;

/// The file as written.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct GroundConfig {
    /// MAVLink in.
    pub input: InputConfig,
    /// The fuser's parameters.
    pub fusion: FuseParams,
    /// What goes out.
    pub outputs: OutputsConfig,
}

/// `[input]`: the MAVLink the drones' tracks arrive on.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct InputConfig {
    /// UDP endpoints: `udpin:HOST:PORT` (listen: a GCS forward or a mavlink-router
    /// `Mode = Normal` endpoint sends here) or `udpout:HOST:PORT` (mavlink-router's
    /// `Mode = Server` endpoint, e.g. its GCS port 14550: the ground sends its heartbeat there
    /// and the router answers with everything it routes).
    pub connections: Vec<String>,
    /// Our system id in the heartbeat (255: a ground station).
    pub system_id: u8,
    /// Our component id in the heartbeat (190: MAV_COMP_ID_MISSIONPLANNER, a GCS).
    pub component_id: u8,
    /// Heartbeats per second (0.1..=10): they tell a router where the ground is.
    pub heartbeat_hz: f64,
    /// Only these vehicles' system ids (empty: every vehicle heard).
    pub vehicles: Vec<u8>,
    /// The autopilot's component id: its SYSTEM_TIME maps the vehicle's clock to UTC and its
    /// GLOBAL_POSITION_INT places the drone.
    pub autopilot_component_id: u8,
    /// Use the radio digest (mgmot's STATUSTEXT positions) of a vehicle from which no
    /// MGMOT_TRACK arrives (its autopilot's radio drops MGMOT_TRACK).
    pub digest: bool,
    /// The uncertainty (DRMS, m) given to a digest position, which carries none.
    pub digest_h_std_m: f64,
}

impl Default for InputConfig {
    fn default() -> Self {
        Self {
            connections: vec!["udpin:0.0.0.0:14550".into()],
            system_id: 255,
            component_id: 190,
            heartbeat_hz: 1.0,
            vehicles: Vec::new(),
            autopilot_component_id: 1,
            digest: true,
            digest_h_std_m: 15.0,
        }
    }
}

/// `[outputs]`.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct OutputsConfig {
    /// Picture updates per second (GeoJSON, map, recording).
    pub rate_hz: f64,
    /// The local web server of the live map (`/`) and the GeoJSON (`/tracks.geojson`);
    /// empty: none. Keep it on 127.0.0.1 unless the network is trusted: it has no login.
    pub http: String,
    /// Write the picture as GeoJSON to this file at every update (replaced atomically);
    /// empty: no file.
    pub geojson: PathBuf,
    /// Record the fused picture (JSON lines, one per update) to this file for
    /// `mgmot review`; empty: no recording.
    pub record: PathBuf,
    /// Fused Cursor-on-Target, as `[outputs.cot]` of `mgmot run` (`vehicle`: also the drones).
    pub cot: CotConfig,
}

impl Default for OutputsConfig {
    fn default() -> Self {
        Self {
            rate_hz: 1.0,
            http: "127.0.0.1:8080".into(),
            geojson: PathBuf::new(),
            record: PathBuf::new(),
            cot: CotConfig::default(),
        }
    }
}

/// A UDP endpoint of the input.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum UdpEndpoint {
    /// Listen here.
    In(SocketAddr),
    /// Send the heartbeat here; take what it sends.
    Out(SocketAddr),
}

/// The validated configuration.
#[derive(Debug, Clone, PartialEq)]
pub struct GroundSettings {
    /// Input endpoints.
    pub connections: Vec<UdpEndpoint>,
    /// `[input]` as written (ids, digest).
    pub input: InputConfig,
    /// Fusion parameters.
    pub fusion: FuseParams,
    /// Between two picture updates.
    pub every: Duration,
    /// The map's address.
    pub http: Option<SocketAddr>,
    /// GeoJSON file.
    pub geojson: Option<PathBuf>,
    /// Recording file.
    pub record: Option<PathBuf>,
    /// Fused CoT.
    pub cot: Option<CotSettings>,
}

fn socket_addr(p: &mut Problems, key: &str, s: &str) -> Option<SocketAddr> {
    use std::net::ToSocketAddrs;
    match s.to_socket_addrs().map(|mut a| a.next()) {
        Ok(Some(a)) => Some(a),
        _ => {
            p.push(
                key,
                format!("must be HOST:PORT (an address this machine can resolve), not {s:?}"),
            );
            None
        }
    }
}

impl GroundConfig {
    /// Reads a file.
    pub fn load(path: &Path) -> Result<Self, ConfigError> {
        let text = std::fs::read_to_string(path).map_err(|source| ConfigError::Read {
            path: path.to_owned(),
            source,
        })?;
        toml::from_str(&text).map_err(|e| ConfigError::Parse {
            path: path.to_owned(),
            message: e.to_string(),
        })
    }

    /// The settings, or every problem found; `source` names where the configuration came
    /// from in the error (the file, or the flags over the defaults).
    pub fn validate(&self, source: &Path) -> Result<GroundSettings, ConfigError> {
        let mut p = Problems::default();
        const CONN: &str = "input.connections";
        if self.input.connections.is_empty() {
            p.push(
                CONN,
                "must name at least one endpoint, e.g. \"udpin:0.0.0.0:14550\"",
            );
        }
        let connections: Vec<UdpEndpoint> = self
            .input
            .connections
            .iter()
            .filter_map(|c| match c.split_once(':') {
                Some(("udpin", addr)) => socket_addr(&mut p, CONN, addr).map(UdpEndpoint::In),
                Some(("udpout", addr)) => socket_addr(&mut p, CONN, addr).map(UdpEndpoint::Out),
                _ => {
                    p.push(
                        CONN,
                        format!(
                            "{c:?}: mgmot ground reads UDP: udpin:HOST:PORT or udpout:HOST:PORT"
                        ),
                    );
                    None
                }
            })
            .collect();
        p.within_closed("input.heartbeat_hz", self.input.heartbeat_hz, 0.1, 10.0);
        p.within_closed(
            "input.digest_h_std_m",
            self.input.digest_h_std_m,
            0.1,
            10_000.0,
        );
        if let Err(e) = self.fusion.validate() {
            p.push("fusion", e);
        }
        let every = p
            .within_closed("outputs.rate_hz", self.outputs.rate_hz, 0.1, 20.0)
            .map(|hz| Duration::from_secs_f64(1.0 / hz));
        let http = (!self.outputs.http.trim().is_empty())
            .then(|| socket_addr(&mut p, "outputs.http", self.outputs.http.trim()))
            .flatten();
        let file = |f: &PathBuf| (!f.as_os_str().is_empty()).then(|| f.clone());
        let cot = self.outputs.cot.validate(&mut p);
        match (p.is_empty(), every, cot) {
            (true, Some(every), Some(cot)) => Ok(GroundSettings {
                connections,
                input: self.input.clone(),
                fusion: self.fusion.clone(),
                every,
                http,
                geojson: file(&self.outputs.geojson),
                record: file(&self.outputs.record),
                cot,
            }),
            _ => Err(ConfigError::Invalid {
                path: source.to_owned(),
                problems: p.into_vec(),
            }),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn defaults_are_valid_and_listen_on_14550() {
        let s = GroundConfig::default().validate(Path::new("x")).unwrap();
        assert_eq!(
            s.connections,
            vec![UdpEndpoint::In("0.0.0.0:14550".parse().unwrap())]
        );
        assert_eq!(s.http, Some("127.0.0.1:8080".parse().unwrap()));
        assert!(s.cot.is_none() && s.geojson.is_none() && s.record.is_none());
    }

    #[test]
    fn every_problem_is_named() {
        let c: GroundConfig = toml::from_str(
            r#"
            [input]
            connections = ["tcpout:1.2.3.4:5760", "udpin:nowhere"]
            heartbeat_hz = 0.0
            [fusion]
            gate_chi2 = -1
            [outputs]
            rate_hz = 100
            http = "x"
            [outputs.cot]
            enabled = true
            url = "http://a:1"
            "#,
        )
        .unwrap();
        let Err(ConfigError::Invalid { problems, .. }) = c.validate(Path::new("x")) else {
            panic!("accepted");
        };
        let text = problems
            .iter()
            .map(ToString::to_string)
            .collect::<Vec<_>>()
            .join("\n");
        for key in [
            "input.connections",
            "input.heartbeat_hz",
            "fusion",
            "outputs.rate_hz",
            "outputs.http",
            "outputs.cot.url",
        ] {
            assert!(text.contains(key), "{key} missing in\n{text}");
        }
        assert!(text.contains("tcpout"), "{text}");
    }

    /// The example file lists every key with its default value.
    #[test]
    fn the_example_file_is_the_defaults() {
        let example: GroundConfig =
            toml::from_str(include_str!("../../systemd/mgmot-ground.example.toml")).unwrap();
        assert_eq!(example, GroundConfig::default());
    }

    #[test]
    fn unknown_keys_are_refused() {
        assert!(toml::from_str::<GroundConfig>("[input]\nconection = []").is_err());
    }
}
