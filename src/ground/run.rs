//! The ground loop: UDP sockets in, the fuser stepped at the output rate, the picture out to
//! the map server, the GeoJSON file, the recording and CoT.

use super::config::{GroundSettings, UdpEndpoint};
use super::cot::{GroundCot, GroundCotSettings};
use super::geojson::collection;
use super::http::{HttpError, MapServer};
use super::ingest::{Ingest, IngestStats};
use super::record::{GroundRecorder, RecordError};
use crate::clock::unix_now_us;
use crate::cot::{CotOutput, CotStats};
use crate::mavlink::dialect::{
    MavAutopilot, MavMessage, MavModeFlag, MavState, MavType, HEARTBEAT_DATA,
};
use crate::mavlink::link::frames::FrameParser;
use crate::mavlink::parse_raw;
use crate::pipeline::Shutdown;
use mavlink_core::{MavHeader, MavlinkVersion};
use mgmot_core::fuse::Fuser;
use serde::Serialize;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::sync::Arc;
use std::time::Duration;
use tokio::net::UdpSocket;
use tokio::sync::mpsc;

/// Why the ground stopped.
#[derive(Debug, thiserror::Error)]
pub enum GroundError {
    /// A socket could not be opened.
    #[error("cannot open the MAVLink input {endpoint}: {source}")]
    Socket {
        /// Which.
        endpoint: String,
        /// Why.
        source: std::io::Error,
    },
    /// The map server.
    #[error(transparent)]
    Http(#[from] HttpError),
    /// The recording.
    #[error(transparent)]
    Record(#[from] RecordError),
    /// The GeoJSON file.
    #[error("writing {path}: {source}")]
    GeoJson {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
}

/// What a run did.
#[derive(Debug, Clone, Default, Serialize)]
pub struct GroundStats {
    /// What arrived.
    pub ingest: IngestStats,
    /// Picture updates made.
    pub updates: u64,
    /// Fused ids ever given.
    pub fused_ids: u64,
    /// Fused ids retired by merges.
    pub retired: u64,
    /// Drones heard.
    pub drones: usize,
    /// CoT counters (when on).
    pub cot: Option<CotCounters>,
}

/// The CoT output's counters at the end.
#[derive(Debug, Clone, Default, Serialize)]
pub struct CotCounters {
    /// Queued.
    pub queued: u64,
    /// Sent.
    pub sent: u64,
    /// Dropped (queue full).
    pub dropped: u64,
    /// Not sent at the end.
    pub unsent_at_exit: u64,
}

impl CotCounters {
    fn of(s: &CotStats, unsent: u64) -> Self {
        use std::sync::atomic::Ordering::Relaxed;
        Self {
            queued: s.queued.load(Relaxed),
            sent: s.sent.load(Relaxed),
            dropped: s.dropped.load(Relaxed),
            unsent_at_exit: unsent,
        }
    }
}

fn now_s() -> f64 {
    unix_now_us() as f64 / 1e6
}

/// A datagram's messages, when they arrived.
type Arrival = (f64, Vec<(MavHeader, MavMessage)>);

/// Opens the sockets and starts one reader task each; returns the sockets (for heartbeats)
/// with their fixed peer (`udpout`).
async fn open_inputs(
    settings: &GroundSettings,
    tx: &mpsc::Sender<Arrival>,
) -> Result<
    Vec<(
        Arc<UdpSocket>,
        Option<SocketAddr>,
        Arc<std::sync::Mutex<Option<SocketAddr>>>,
    )>,
    GroundError,
> {
    let mut out = Vec::new();
    for ep in &settings.connections {
        let (bind, remote, name) = match ep {
            UdpEndpoint::In(a) => (*a, None, format!("udpin:{a}")),
            UdpEndpoint::Out(a) => {
                let any: SocketAddr = if a.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                (any, Some(*a), format!("udpout:{a}"))
            }
        };
        let socket = UdpSocket::bind(bind)
            .await
            .map_err(|source| GroundError::Socket {
                endpoint: name.clone(),
                source,
            })?;
        tracing::info!(endpoint = %name, local = ?socket.local_addr().ok(), "listening for MAVLink");
        let socket = Arc::new(socket);
        let peer = Arc::new(std::sync::Mutex::new(None));
        let (s, tx, peer_w) = (socket.clone(), tx.clone(), peer.clone());
        tokio::spawn(async move {
            let mut buf = vec![0u8; 65_536];
            let mut parser = FrameParser::new();
            loop {
                let (n, from) = match s.recv_from(&mut buf).await {
                    Ok(x) => x,
                    // An ICMP "port unreachable" of a udpout peer that is not up yet.
                    Err(e) => {
                        tracing::debug!(error = %e, "MAVLink input: receive error");
                        tokio::time::sleep(Duration::from_millis(100)).await;
                        continue;
                    }
                };
                if remote.is_some_and(|r| r != from) {
                    continue;
                }
                if let Ok(mut p) = peer_w.lock() {
                    *p = Some(from);
                }
                let messages: Vec<(MavHeader, MavMessage)> = parser
                    .push_datagram(&buf[..n])
                    .iter()
                    .filter_map(|raw| parse_raw(raw).ok())
                    .collect();
                if !messages.is_empty() && tx.send((now_s(), messages)).await.is_err() {
                    return;
                }
            }
        });
        out.push((socket, remote, peer));
    }
    Ok(out)
}

/// Runs until `shutdown` (or `duration`, for benches and tests).
pub async fn run(
    settings: GroundSettings,
    effective_config: serde_json::Value,
    mut shutdown: Shutdown,
    duration: Option<Duration>,
) -> Result<GroundStats, GroundError> {
    let (tx, mut rx) = mpsc::channel::<Arrival>(4096);
    let inputs = open_inputs(&settings, &tx).await?;
    drop(tx);
    let server = settings.http.map(MapServer::start).transpose()?;
    if let Some(s) = &server {
        tracing::info!("live map on http://{}/", s.addr);
        eprintln!("mgmot ground: live map on http://{}/", s.addr);
    }
    let mut recorder = settings
        .record
        .as_deref()
        .map(|p| GroundRecorder::create(p, &effective_config))
        .transpose()?;
    let run_tag = chrono::DateTime::from_timestamp_micros(unix_now_us())
        .unwrap_or_default()
        .format("%Y%m%dT%H%M%SZ")
        .to_string();
    let (mut cot, cot_out) = match &settings.cot {
        Some(c) => {
            let cot_settings = GroundCotSettings {
                stale_us: c.stale.as_micros() as i64,
                every_us: c.every.as_micros() as i64,
                types: c.types.clone(),
                callsign: c.callsign.clone().unwrap_or_else(|| "mgmot ground".into()),
                run_tag,
                drones: c.vehicle,
            };
            let publisher = GroundCot::new(cot_settings.clone());
            let identity = GroundCot::new(cot_settings);
            let out = CotOutput::spawn(c, Box::new(move || identity.identity(unix_now_us())));
            (Some(publisher), Some(out))
        }
        None => (None, None),
    };
    let mut fuser = Fuser::new(settings.fusion.clone());
    let mut ingest = Ingest::new(settings.input.clone());
    let mut stats = GroundStats::default();
    let mut tick = tokio::time::interval(settings.every);
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut heartbeat =
        tokio::time::interval(Duration::from_secs_f64(1.0 / settings.input.heartbeat_hz));
    let end = duration.map(|d| tokio::time::Instant::now() + d);
    let mut sequence: u8 = 0;
    loop {
        let until_end = async {
            match end {
                Some(e) => tokio::time::sleep_until(e).await,
                None => std::future::pending().await,
            }
        };
        tokio::select! {
            _ = shutdown.recv() => break,
            _ = until_end => break,
            arrival = rx.recv() => {
                let Some((arrival_s, messages)) = arrival else { break };
                for (h, m) in &messages {
                    ingest.message(h, m, arrival_s, &mut fuser);
                }
            }
            _ = heartbeat.tick() => {
                let bytes = heartbeat_bytes(&settings, sequence);
                sequence = sequence.wrapping_add(1);
                for (socket, remote, peer) in &inputs {
                    let to = remote.or_else(|| peer.lock().ok().and_then(|p| *p));
                    if let Some(to) = to {
                        let _ = socket.send_to(&bytes, to).await;
                    }
                }
            }
            _ = tick.tick() => {
                let ground_s = now_s();
                let now = ingest.now(ground_s);
                fuser.step(now);
                let picture = fuser.picture(now);
                let retired = fuser.take_retired();
                stats.retired += retired.len() as u64;
                stats.updates += 1;
                let geojson = collection(now, ground_s, &picture, ingest.drones());
                if let Some(server) = &server {
                    server.publish(Arc::from(geojson.to_string()));
                }
                if let Some(path) = &settings.geojson {
                    write_atomic(path, geojson.to_string().as_bytes())
                        .map_err(|source| GroundError::GeoJson { path: path.clone(), source })?;
                }
                if let Some(r) = &mut recorder {
                    r.update(&geojson)?;
                }
                if let (Some(cot), Some(out)) = (&mut cot, &cot_out) {
                    for m in cot.events(&picture, &retired, ingest.drones(), unix_now_us()) {
                        out.send(m);
                    }
                }
            }
        }
    }
    stats.ingest = ingest.stats().clone();
    stats.drones = ingest.drones().count();
    stats.fused_ids = fuser.ids_given();
    if let Some(out) = cot_out {
        let shared = out.shared_stats();
        let unsent = tokio::task::spawn_blocking(move || out.close(Duration::from_secs(2)))
            .await
            .unwrap_or(0);
        stats.cot = Some(CotCounters::of(&shared, unsent));
    }
    if let Some(s) = server {
        let _ = tokio::task::spawn_blocking(move || s.stop()).await;
    }
    Ok(stats)
}

/// Our GCS heartbeat, so a router's server endpoint learns where we are.
fn heartbeat_bytes(settings: &GroundSettings, sequence: u8) -> Vec<u8> {
    let msg = MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        custom_mode: 0,
        mavtype: MavType::MAV_TYPE_GCS,
        autopilot: MavAutopilot::MAV_AUTOPILOT_INVALID,
        base_mode: MavModeFlag::empty(),
        system_status: MavState::MAV_STATE_ACTIVE,
        mavlink_version: 3,
    });
    let header = MavHeader {
        system_id: settings.input.system_id.into(),
        component_id: settings.input.component_id,
        sequence,
    };
    let mut buf = Vec::new();
    // Writing to a Vec cannot fail.
    let _ = mavlink_core::write_versioned_msg(&mut buf, MavlinkVersion::V2, header, &msg);
    buf
}

/// Writes `path` through a temporary file beside it and a rename: a reader never sees half.
fn write_atomic(path: &std::path::Path, bytes: &[u8]) -> std::io::Result<()> {
    let mut tmp = path.as_os_str().to_owned();
    tmp.push(".tmp");
    std::fs::write(&tmp, bytes)?;
    std::fs::rename(&tmp, path)
}
