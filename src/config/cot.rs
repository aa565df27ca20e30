//! `[outputs.cot]`: Cursor-on-Target events for TAK maps (ATAK, WinTAK, iTAK, a TAK server).
//! Off unless `enabled = true`.

use super::problems::{period, Problems};
use crate::cot::{default_types, TypesByClass};
use serde::{Deserialize, Serialize};
use std::net::Ipv4Addr;
use std::path::PathBuf;
use std::time::Duration;

/// The CoT output as written in the file.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CotConfig {
    /// Send CoT events.
    pub enabled: bool,
    /// Where: `udp://239.2.3.1:6969` (the TAK situational-awareness multicast group, the
    /// default), `udp://HOST:PORT` (unicast), `tcp://HOST:PORT` (a TAK server's streaming
    /// port, 8087 usually) or `tls://HOST:PORT` (its TLS port, 8089, with `[outputs.cot.tls]`).
    pub url: String,
    /// Events per track per second.
    pub rate_hz: f64,
    /// How long an event stays valid on the map (s): a track that is no longer reported
    /// greys out after this long.
    pub stale_s: f64,
    /// The vehicle's callsign on the map; empty: `mgmot-<system id>`.
    pub callsign: String,
    /// Also send the vehicle itself (its position and the camera's heading) and the camera's
    /// footprint on the sea (a TAK drawing), at the same rate.
    pub vehicle: bool,
    /// For a multicast `url`: the address of the interface to send on (empty: the kernel's
    /// choice, the default route's interface).
    pub multicast_interface: String,
    /// For a multicast `url`: the time to live (1: this network only).
    pub multicast_ttl: u32,
    /// Events waiting to be sent; when the link is slower than the tracks, older events of a
    /// track are replaced by newer ones, never the frame path held up.
    pub queue: usize,
    /// The longest wait between two attempts to reach a TCP or TLS server (s); the wait
    /// doubles from 0.5 s up to this.
    pub reconnect_max_s: f64,
    /// The CoT type of each class.
    pub types: CotTypes,
    /// For `tls://`: the client certificate and the server's CA.
    pub tls: Option<CotTlsConfig>,
}

impl Default for CotConfig {
    fn default() -> Self {
        Self {
            enabled: false,
            url: "udp://239.2.3.1:6969".into(),
            rate_hz: 1.0,
            stale_s: 60.0,
            callsign: String::new(),
            vehicle: true,
            multicast_interface: String::new(),
            multicast_ttl: 1,
            queue: 1024,
            reconnect_max_s: 10.0,
            types: CotTypes::default(),
            tls: None,
        }
    }
}

/// `[outputs.cot.types]`: the CoT type of each class.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct CotTypes {
    /// A class the model does not name.
    pub object: String,
    /// A person in the water.
    pub swimmer: String,
    /// A boat.
    pub boat: String,
    /// A jetski.
    pub jetski: String,
    /// A life ring, life jacket or raft.
    pub life_saving_appliances: String,
    /// A buoy.
    pub buoy: String,
}

impl Default for CotTypes {
    fn default() -> Self {
        let [object, swimmer, boat, jetski, life_saving_appliances, buoy] = default_types();
        Self {
            object,
            swimmer,
            boat,
            jetski,
            life_saving_appliances,
            buoy,
        }
    }
}

/// `[outputs.cot.tls]`: PEM files for a `tls://` server.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CotTlsConfig {
    /// This client's certificate (PEM; the chain, leaf first).
    pub cert: PathBuf,
    /// Its private key (PEM; PKCS#8, PKCS#1 or SEC1).
    pub key: PathBuf,
    /// The CA that signed the server's certificate (PEM). A TAK server's own CA, usually.
    pub ca: PathBuf,
    /// Check that the server's certificate names the host of `url` (TAK servers often have
    /// certificates for another name; the chain to `ca` is always checked).
    #[serde(default = "yes")]
    pub verify_hostname: bool,
}

fn yes() -> bool {
    true
}

/// Where the events go.
#[derive(Debug, Clone, PartialEq)]
pub enum CotEndpoint {
    /// UDP datagrams, one event each; multicast when `host` is a multicast address.
    Udp {
        /// Host name or address.
        host: String,
        /// Port.
        port: u16,
        /// Interface to send multicast on.
        multicast_interface: Option<Ipv4Addr>,
        /// Multicast time to live.
        multicast_ttl: u32,
    },
    /// A TCP stream of events (a TAK server's streaming port).
    Tcp {
        /// Host name or address.
        host: String,
        /// Port.
        port: u16,
    },
    /// TCP with TLS and a client certificate.
    Tls {
        /// Host name or address.
        host: String,
        /// Port.
        port: u16,
        /// The PEM files.
        files: CotTlsConfig,
    },
}

impl std::fmt::Display for CotEndpoint {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Udp { host, port, .. } => write!(f, "udp://{host}:{port}"),
            Self::Tcp { host, port } => write!(f, "tcp://{host}:{port}"),
            Self::Tls { host, port, .. } => write!(f, "tls://{host}:{port}"),
        }
    }
}

/// The validated CoT output.
#[derive(Debug, Clone, PartialEq)]
pub struct CotSettings {
    /// Where.
    pub endpoint: CotEndpoint,
    /// Between two events of one track.
    pub every: Duration,
    /// Validity of an event.
    pub stale: Duration,
    /// The vehicle's callsign; `None`: `mgmot-<system id>`.
    pub callsign: Option<String>,
    /// Send the vehicle itself.
    pub vehicle: bool,
    /// CoT type by class id.
    pub types: TypesByClass,
    /// Events waiting to be sent.
    pub queue: usize,
    /// Longest wait between two connection attempts.
    pub reconnect_max: Duration,
}

impl CotConfig {
    /// The settings (`None` inside when off), or the problems pushed onto `p`.
    pub fn validate(&self, p: &mut Problems) -> Option<Option<CotSettings>> {
        if !self.enabled {
            return Some(None);
        }
        const URL: &str = "outputs.cot.url";
        let endpoint = match parse_url(&self.url) {
            Ok((scheme, host, port)) => self.endpoint(p, scheme, host, port),
            Err(e) => {
                p.push(URL, e);
                None
            }
        };
        const RATE: &str = "outputs.cot.rate_hz";
        let every = p
            .within_open(RATE, self.rate_hz, 0.0, 50.0)
            .and_then(|hz| period(p, RATE, hz));
        let stale = p
            .within_closed("outputs.cot.stale_s", self.stale_s, 1.0, 86_400.0)
            .map(Duration::from_secs_f64);
        let reconnect_max = p
            .within_closed(
                "outputs.cot.reconnect_max_s",
                self.reconnect_max_s,
                0.5,
                600.0,
            )
            .map(Duration::from_secs_f64);
        let queue = p.check(
            (16..=1_000_000).contains(&self.queue),
            "outputs.cot.queue",
            "must be in 16..=1000000 events",
            self.queue,
        );
        let callsign = self.callsign.trim();
        let callsign = p.check(
            callsign.chars().count() <= 64,
            "outputs.cot.callsign",
            "must be at most 64 characters",
            (!callsign.is_empty()).then(|| callsign.to_owned()),
        );
        let t = &self.types;
        let types = [
            ("object", &t.object),
            ("swimmer", &t.swimmer),
            ("boat", &t.boat),
            ("jetski", &t.jetski),
            ("life_saving_appliances", &t.life_saving_appliances),
            ("buoy", &t.buoy),
        ]
        .map(|(name, v)| {
            p.check(
                is_cot_type(v),
                &format!("outputs.cot.types.{name}"),
                "must be a CoT type: dash-separated letters and digits, e.g. a-n-G",
                v.clone(),
            )
        });
        let types = if types.iter().all(Option::is_some) {
            Some(types.map(Option::unwrap_or_default))
        } else {
            None
        };
        Some(Some(CotSettings {
            endpoint: endpoint?,
            every: every?,
            stale: stale?,
            callsign: callsign?,
            vehicle: self.vehicle,
            types: types?,
            queue: queue?,
            reconnect_max: reconnect_max?,
        }))
    }

    fn endpoint(
        &self,
        p: &mut Problems,
        scheme: &str,
        host: String,
        port: u16,
    ) -> Option<CotEndpoint> {
        match scheme {
            "udp" => {
                let iface = self.multicast_interface.trim();
                let multicast_interface = if iface.is_empty() {
                    Some(None)
                } else {
                    match iface.parse::<Ipv4Addr>() {
                        Ok(a) => Some(Some(a)),
                        Err(_) => {
                            p.push(
                                "outputs.cot.multicast_interface",
                                format!("{iface:?} is not an IPv4 address"),
                            );
                            None
                        }
                    }
                };
                let ttl = p.check(
                    self.multicast_ttl <= 255,
                    "outputs.cot.multicast_ttl",
                    "must be in 0..=255",
                    self.multicast_ttl,
                );
                Some(CotEndpoint::Udp {
                    host,
                    port,
                    multicast_interface: multicast_interface?,
                    multicast_ttl: ttl?,
                })
            }
            "tcp" => Some(CotEndpoint::Tcp { host, port }),
            "tls" => {
                let Some(files) = &self.tls else {
                    p.push(
                        "outputs.cot.tls",
                        "a tls:// url needs [outputs.cot.tls] with cert, key and ca",
                    );
                    return None;
                };
                let mut ok = true;
                for (key, path) in [
                    ("cert", &files.cert),
                    ("key", &files.key),
                    ("ca", &files.ca),
                ] {
                    if !path.is_file() {
                        p.push(
                            &format!("outputs.cot.tls.{key}"),
                            format!("{} is not a readable file", path.display()),
                        );
                        ok = false;
                    }
                }
                ok.then(|| CotEndpoint::Tls {
                    host,
                    port,
                    files: files.clone(),
                })
            }
            _ => None,
        }
    }
}

/// `scheme://host:port` with a scheme of udp, tcp or tls.
fn parse_url(url: &str) -> Result<(&str, String, u16), String> {
    let (scheme, rest) = url
        .split_once("://")
        .ok_or_else(|| format!("{url:?} is not SCHEME://HOST:PORT (udp, tcp or tls)"))?;
    if !matches!(scheme, "udp" | "tcp" | "tls") {
        return Err(format!(
            "{url:?}: the scheme must be udp, tcp or tls, not {scheme:?}"
        ));
    }
    let rest = rest.trim_end_matches('/');
    let (host, port) = rest
        .rsplit_once(':')
        .ok_or_else(|| format!("{url:?} has no port (SCHEME://HOST:PORT)"))?;
    let port: u16 = port
        .parse()
        .ok()
        .filter(|p| *p > 0)
        .ok_or_else(|| format!("{url:?}: {port:?} is not a port (1..=65535)"))?;
    let host = host.trim_start_matches('[').trim_end_matches(']');
    if host.is_empty() {
        return Err(format!("{url:?} has no host"));
    }
    Ok((scheme, host.to_owned(), port))
}

/// A CoT type: letters, digits and `.`/`_` in dash-separated parts.
fn is_cot_type(t: &str) -> bool {
    !t.is_empty()
        && t.len() <= 64
        && t.split('-').all(|part| {
            !part.is_empty()
                && part
                    .chars()
                    .all(|c| c.is_ascii_alphanumeric() || c == '.' || c == '_')
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn validate(c: &CotConfig) -> Result<Option<CotSettings>, Vec<String>> {
        let mut p = Problems::default();
        let s = c.validate(&mut p);
        if p.is_empty() {
            Ok(s.unwrap())
        } else {
            Err(p.into_vec().iter().map(ToString::to_string).collect())
        }
    }

    #[test]
    fn off_by_default_and_the_default_is_the_sa_multicast_group() {
        assert_eq!(validate(&CotConfig::default()), Ok(None));
        let on = CotConfig {
            enabled: true,
            ..CotConfig::default()
        };
        let s = validate(&on).unwrap().unwrap();
        assert_eq!(s.endpoint.to_string(), "udp://239.2.3.1:6969");
        assert_eq!(s.every, Duration::from_secs(1));
        assert_eq!(s.types[1], "a-n-G");
    }

    #[test]
    fn bad_values_are_named() {
        for (url, expect) in [
            ("http://x:1", "scheme"),
            ("tcp://x", "no port"),
            ("tcp://x:0", "not a port"),
            ("tcp://:8087", "no host"),
            ("tls://x:8089", "[outputs.cot.tls]"),
        ] {
            let c = CotConfig {
                enabled: true,
                url: url.into(),
                ..CotConfig::default()
            };
            let e = validate(&c).unwrap_err().join("; ");
            assert!(e.contains(expect), "{url}: {e}");
        }
        let c = CotConfig {
            enabled: true,
            rate_hz: 0.0,
            multicast_interface: "eth0".into(),
            types: CotTypes {
                swimmer: "a n G".into(),
                ..CotTypes::default()
            },
            ..CotConfig::default()
        };
        let e = validate(&c).unwrap_err().join("; ");
        for key in [
            "outputs.cot.rate_hz",
            "outputs.cot.multicast_interface",
            "outputs.cot.types.swimmer",
        ] {
            assert!(e.contains(key), "{e}");
        }
    }

    #[test]
    fn tls_files_must_exist() {
        let c = CotConfig {
            enabled: true,
            url: "tls://tak.local:8089".into(),
            tls: Some(CotTlsConfig {
                cert: "/nonexistent/c.pem".into(),
                key: "/nonexistent/k.pem".into(),
                ca: "/nonexistent/ca.pem".into(),
                verify_hostname: false,
            }),
            ..CotConfig::default()
        };
        let e = validate(&c).unwrap_err().join("; ");
        assert!(
            e.contains("outputs.cot.tls.cert") && e.contains("outputs.cot.tls.ca"),
            "{e}"
        );
    }

    #[test]
    fn urls_parse() {
        assert_eq!(
            parse_url("tcp://[::1]:8087/"),
            Ok(("tcp", "::1".to_owned(), 8087))
        );
        assert_eq!(
            parse_url("udp://239.2.3.1:6969"),
            Ok(("udp", "239.2.3.1".to_owned(), 6969))
        );
    }
}
