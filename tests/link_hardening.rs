//! The MAVLink link against a hostile or faulty network, over real UDP and TCP sockets on
//! loopback: the test plays the autopilot, a ground station and an attacker, each with a
//! socket of its own, against `mgmot::mavlink::Link` (issue "Hardening": numbered items in
//! the test names).

use mavlink_core::{MAVLinkV2MessageRaw, MavHeader, MessageData};
use mgmot::mavlink::dialect::{
    MavAutopilot, MavCmd, MavMessage, MavResult, COMMAND_ACK_DATA, COMMAND_LONG_DATA,
    GLOBAL_POSITION_INT_DATA, HEARTBEAT_DATA, HOME_POSITION_DATA, STATUSTEXT_DATA, TIMESYNC_DATA,
};
use mgmot::mavlink::link::frames::FrameParser;
use mgmot::mavlink::{parse_raw, Link, LinkEvent, LinkSender, LinkSettings, SigningSettings};
use std::net::{SocketAddr, UdpSocket};
use std::time::{Duration, Instant};
use tokio::sync::mpsc;

use crate::common::{free_udp_port, TestDir};

const AUTOPILOT: (u8, u8) = (1, 1);
/// MOUNT_ORIENTATION's id (the message is deprecated in common.xml).
#[allow(deprecated)]
const MOUNT_ORIENTATION: u32 = mgmot::mavlink::dialect::MOUNT_ORIENTATION_DATA::ID;
const GCS: (u8, u8) = (255, 190);
const KEY: [u8; 32] = [0x5a; 32];

fn settings(connection: String) -> LinkSettings {
    LinkSettings {
        connection,
        system_id: 1,
        component_id: 191,
        autopilot_component_id: 1,
        udp_peer: None,
        signing: None,
        streams: Vec::new(),
        timesync_hz: 0.0,
        accept_unsigned_telemetry: true,
        tap: None,
    }
}

/// One MAVLink 2 frame from `from`, signed with `sign` = (key, link id, timestamp) if given.
fn frame(from: (u8, u8), m: &MavMessage, sign: Option<([u8; 32], u8, u64)>) -> Vec<u8> {
    let header = MavHeader {
        system_id: u32::from(from.0),
        component_id: from.1,
        sequence: 0,
    };
    let mut raw = MAVLinkV2MessageRaw::new();
    match sign {
        None => raw.serialize_message(header, m),
        Some((key, link, ts)) => {
            raw.serialize_message_for_signing(header, m);
            raw.signature_timestamp_bytes_mut()
                .copy_from_slice(&ts.to_le_bytes()[..6]);
            *raw.signature_link_id_mut() = link;
            let mut sig = [0u8; 6];
            raw.calculate_signature(&key, &mut sig);
            raw.signature_value_mut().copy_from_slice(&sig);
        }
    }
    raw.raw_bytes().to_vec()
}

fn heartbeat() -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())
}

fn position(lat_e7: i32) -> MavMessage {
    MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
        time_boot_ms: 1000,
        lat: lat_e7,
        lon: 100_000_000,
        alt: 10_000,
        relative_alt: 10_000,
        ..Default::default()
    })
}

fn statustext(k: u8) -> MavMessage {
    let mut text = [0u8; 50];
    text[0] = b'a' + (k % 26);
    MavMessage::STATUSTEXT(STATUSTEXT_DATA {
        text: text.into(),
        ..Default::default()
    })
}

/// What a peer received: header, message (if the dialect decodes it), raw payload, signature
/// timestamp (if signed).
type Got = (MavHeader, Option<MavMessage>, Vec<u8>, Option<u64>);

/// A UDP endpoint of the test (autopilot, GCS or attacker).
struct Peer {
    socket: UdpSocket,
}

impl Peer {
    fn new() -> Peer {
        let socket = UdpSocket::bind("127.0.0.1:0").unwrap();
        socket
            .set_read_timeout(Some(Duration::from_millis(20)))
            .unwrap();
        Peer { socket }
    }

    fn send(&self, to: SocketAddr, bytes: &[u8]) {
        self.socket.send_to(bytes, to).unwrap();
    }

    /// Every message received within `d`: header, message (if the dialect decodes it), raw
    /// payload, signature timestamp (if signed).
    fn receive_for(&self, d: Duration) -> Vec<Got> {
        let until = Instant::now() + d;
        let mut out = Vec::new();
        let mut buf = [0u8; 2048];
        while Instant::now() < until {
            if let Ok(n) = self.socket.recv(&mut buf) {
                let mut p = FrameParser::new();
                for raw in p.push(&buf[..n]) {
                    let payload = raw.payload().to_vec();
                    let header = MavHeader {
                        system_id: raw.system_id(),
                        component_id: raw.component_id(),
                        sequence: raw.sequence(),
                    };
                    let signed_ts = match &raw {
                        mavlink_core::MAVLinkMessageRaw::V2(v2)
                            if v2.incompatibility_flags() & 1 != 0 =>
                        {
                            Some(v2.signature_timestamp())
                        }
                        _ => None,
                    };
                    out.push((
                        header,
                        parse_raw(&raw).ok().map(|(_, m)| m),
                        payload,
                        signed_ts,
                    ));
                }
            }
        }
        out
    }
}

async fn events_for(events: &mut mpsc::Receiver<LinkEvent>, d: Duration) -> Vec<LinkEvent> {
    let mut out = Vec::new();
    let until = tokio::time::Instant::now() + d;
    while let Ok(Some(e)) = tokio::time::timeout_at(until, events.recv()).await {
        out.push(e);
    }
    out
}

fn positions(events: &[LinkEvent]) -> Vec<(u8, i32)> {
    events
        .iter()
        .filter_map(|e| match e {
            LinkEvent::Message(r) => match &r.message {
                MavMessage::GLOBAL_POSITION_INT(p) => Some((r.system_id, p.lat)),
                _ => None,
            },
            LinkEvent::TimeSync { .. } => None,
        })
        .collect()
}

fn start(s: LinkSettings) -> (Link, LinkSender, mpsc::Receiver<LinkEvent>) {
    Link::start(s).unwrap()
}

/// Item 1: with `udpin`, replies go to the autopilot that spoke first, not to whoever sent
/// the last datagram; 100 junk datagrams a second from another peer change nothing.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item1_udpin_answers_its_peer_not_the_last_sender() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let (link, sender, _events) = start(settings(format!("udpin:127.0.0.1:{port}")));
    let autopilot = Peer::new();
    let attacker = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    autopilot.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    tokio::time::sleep(Duration::from_millis(100)).await;
    let junk = std::thread::spawn({
        let attacker = attacker.socket.try_clone().unwrap();
        move || {
            for k in 0..100u32 {
                let _ = attacker.send_to(&[0xFD, 9, 0, 0, k as u8, 42, 1], addr);
                let _ = attacker.send_to(&frame((42, 1), &heartbeat(), None), addr);
                std::thread::sleep(Duration::from_millis(10));
            }
        }
    });
    for k in 0..50 {
        sender.send(statustext(k));
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
    junk.join().unwrap();
    let to_autopilot = autopilot.receive_for(Duration::from_millis(300));
    let to_attacker = attacker.receive_for(Duration::from_millis(300));
    let stats = link.close().await;
    let texts = to_autopilot
        .iter()
        .filter(|(_, m, _, _)| matches!(m, Some(MavMessage::STATUSTEXT(_))))
        .count();
    assert_eq!(texts, 50, "the autopilot got {texts} of 50");
    assert!(
        to_attacker.is_empty(),
        "the attacker got {} messages",
        to_attacker.len()
    );
    assert!(stats.from_other_peers >= 100, "{stats:?}");
}

/// Item 2: pose and home come only from the configured autopilot; a GLOBAL_POSITION_INT or
/// HOME_POSITION from system 42 (even through the same peer, as a router would forward it)
/// never reaches the pipeline.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item2_telemetry_only_from_the_configured_autopilot() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let (link, _sender, mut events) = start(settings(format!("udpin:127.0.0.1:{port}")));
    let router = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    router.send(addr, &frame(AUTOPILOT, &position(500_000_000), None));
    router.send(addr, &frame((42, 1), &position(510_000_000), None));
    router.send(addr, &frame((1, 42), &position(520_000_000), None));
    let home = MavMessage::HOME_POSITION(HOME_POSITION_DATA {
        latitude: 510_000_000,
        longitude: 1,
        altitude: -20_000,
        ..Default::default()
    });
    router.send(addr, &frame((42, 1), &home, None));
    router.send(addr, &frame(AUTOPILOT, &position(500_000_100), None));
    let got = events_for(&mut events, Duration::from_millis(500)).await;
    let stats = link.close().await;
    assert_eq!(positions(&got), [(1, 500_000_000), (1, 500_000_100)]);
    assert!(
        !got.iter().any(|e| matches!(e, LinkEvent::Message(r) if matches!(r.message, MavMessage::HOME_POSITION(_)))),
        "a spoofed HOME_POSITION got through"
    );
    assert_eq!(stats.telemetry_from_others, 3, "{stats:?}");
}

/// Item 3: a TIMESYNC answer counts only when it answers one of our requests, once, from the
/// autopilot: a ground station's answer (forwarded by the autopilot), a made-up ts1 and a
/// repeated answer are all ignored.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item3_timesync_answers_must_match_our_requests() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let mut s = settings(format!("udpin:127.0.0.1:{port}"));
    s.timesync_hz = 5.0;
    let (link, _sender, mut events) = start(s);
    let autopilot = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    autopilot.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    // Collect a request of ours.
    let request = loop {
        let got = autopilot.receive_for(Duration::from_millis(300));
        if let Some(t) = got.iter().find_map(|(_, m, _, _)| match m {
            Some(MavMessage::TIMESYNC(t)) if t.tc1 == 0 => Some(t.clone()),
            _ => None,
        }) {
            break t;
        }
        autopilot.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    };
    assert_eq!((request.target_system, request.target_component), AUTOPILOT);
    let answer = |ts1: i64| {
        MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 123_000_000,
            ts1,
            target_system: 1,
            target_component: 191,
        })
    };
    autopilot.send(addr, &frame(GCS, &answer(request.ts1), None)); // a GCS answering
    autopilot.send(addr, &frame(AUTOPILOT, &answer(request.ts1 + 7), None)); // not ours
    autopilot.send(addr, &frame(AUTOPILOT, &answer(request.ts1), None)); // the real one
    autopilot.send(addr, &frame(AUTOPILOT, &answer(request.ts1), None)); // again
    let got = events_for(&mut events, Duration::from_millis(400)).await;
    let stats = link.close().await;
    let syncs: Vec<_> = got
        .iter()
        .filter_map(|e| match e {
            LinkEvent::TimeSync {
                sent, autopilot, ..
            } => Some((sent.0, autopilot.0)),
            LinkEvent::Message(_) => None,
        })
        .collect();
    assert_eq!(syncs, [(request.ts1 as u64 / 1000, 123_000)]);
    assert!(stats.timesync_unmatched >= 2, "{stats:?}");
}

fn now_signing() -> u64 {
    mgmot::mavlink::signing::signing_now()
}

/// A `udpin` link on a free loopback port, signing with [`KEY`] (link id 3) and keeping its
/// timestamps in `state`; the address to send to it.
fn signed_udpin(state: &std::path::Path) -> (SocketAddr, LinkSettings) {
    let port = free_udp_port();
    let mut s = settings(format!("udpin:127.0.0.1:{port}"));
    s.signing = Some(SigningSettings {
        key: KEY,
        link_id: 3,
        state_file: Some(state.to_path_buf()),
    });
    (([127, 0, 0, 1], port).into(), s)
}

/// Item 4: one signed frame stamped 120 s ahead is refused, correctly timed frames after it
/// still pass, and mgmot's own signing timestamps stay on its clock; a signed command
/// captured before a restart is refused after it (the state file).
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item4_signing_clock_cannot_be_pushed_and_survives_restarts() {
    let dir = TestDir::new();
    let state = dir.path().join("signing.json");
    let (addr, s) = signed_udpin(&state);
    let (link, sender, mut events) = start(s.clone());
    let autopilot = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let t0 = now_signing();
    autopilot.send(
        addr,
        &frame(AUTOPILOT, &position(500_000_000), Some((KEY, 0, t0))),
    );
    autopilot.send(
        addr,
        &frame(
            AUTOPILOT,
            &position(510_000_000),
            Some((KEY, 0, t0 + 120 * 100_000)),
        ),
    );
    autopilot.send(
        addr,
        &frame(AUTOPILOT, &position(500_000_200), Some((KEY, 0, t0 + 2))),
    );
    autopilot.send(
        addr,
        &frame(
            AUTOPILOT,
            &position(510_000_000),
            Some((KEY, 0, (1 << 48) - 2)),
        ),
    );
    autopilot.send(
        addr,
        &frame(AUTOPILOT, &position(500_000_300), Some((KEY, 0, t0 + 3))),
    );
    let stop = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
        target_system: 1,
        target_component: 191,
        ..Default::default()
    });
    let captured_stop = frame(GCS, &stop, Some((KEY, 1, t0 + 10)));
    autopilot.send(addr, &captured_stop);
    tokio::time::sleep(Duration::from_millis(50)).await;
    sender.send(heartbeat());
    let got = events_for(&mut events, Duration::from_millis(400)).await;
    let ours = autopilot.receive_for(Duration::from_millis(200));
    let stats = link.close().await;
    assert_eq!(
        positions(&got),
        [(1, 500_000_000), (1, 500_000_200), (1, 500_000_300)],
        "frames ahead of the clock refused, later ones still accepted"
    );
    let commands = got
        .iter()
        .filter(|e| matches!(e, LinkEvent::Message(r) if r.signed && matches!(r.message, MavMessage::COMMAND_LONG(_))))
        .count();
    assert_eq!(commands, 1);
    assert_eq!(stats.signing_refused, 2, "{stats:?}");
    // Our timestamps: signed, on our clock, neither 120 s ahead nor wrapped.
    let after = now_signing();
    let stamps: Vec<u64> = ours.iter().filter_map(|g| g.3).collect();
    assert!(
        !stamps.is_empty() && stamps.len() == ours.len(),
        "unsigned frames sent"
    );
    for ts in stamps {
        assert!(
            ts >= t0 && ts <= after + 100_000,
            "our timestamp {ts} is off our clock {after}"
        );
    }

    // Restart: the STOP captured before it is a replay.
    let (link, _sender, mut events) = start(s);
    tokio::time::sleep(Duration::from_millis(200)).await;
    let hb = frame(AUTOPILOT, &heartbeat(), Some((KEY, 0, now_signing())));
    autopilot.send(addr, &hb); // the autopilot is the peer again
    autopilot.send(addr, &captured_stop);
    let got = events_for(&mut events, Duration::from_millis(400)).await;
    let stats = link.close().await;
    let replayed = got.iter().any(
        |e| matches!(e, LinkEvent::Message(r) if matches!(r.message, MavMessage::COMMAND_LONG(_))),
    );
    assert!(!replayed, "replayed after a restart: {got:?}");
    assert_eq!(stats.signing_refused, 1);
}

/// Issue 39 item 11: a signed command accepted just before a SIGKILL cannot be replayed after
/// the restart. The state file is copied the moment the command reaches the link's consumer
/// (what a SIGKILL then would leave on disk: no periodic save, no save at close), and the
/// restarted link starts from that copy.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn issue39_item11_a_signed_command_is_persisted_before_it_is_acted_on() {
    let dir = TestDir::new();
    let state = dir.path().join("signing.json");
    let at_kill = dir.path().join("signing-at-kill.json");
    let (addr, s) = signed_udpin(&state);
    let (link, _sender, mut events) = start(s.clone());
    let autopilot = Peer::new();
    tokio::time::sleep(Duration::from_millis(100)).await;
    let t0 = now_signing();
    autopilot.send(addr, &frame(AUTOPILOT, &heartbeat(), Some((KEY, 0, t0))));
    let stop = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
        target_system: 1,
        target_component: 191,
        ..Default::default()
    });
    let captured_stop = frame(GCS, &stop, Some((KEY, 1, t0 + 10)));
    autopilot.send(addr, &captured_stop);
    let until = tokio::time::Instant::now() + Duration::from_secs(2);
    loop {
        let e = tokio::time::timeout_at(until, events.recv())
            .await
            .expect("the command within 2 s")
            .expect("the link is up");
        if matches!(&e, LinkEvent::Message(r) if matches!(r.message, MavMessage::COMMAND_LONG(_))) {
            // Acted on now: the state on disk is what a SIGKILL would leave.
            std::fs::copy(&state, &at_kill).unwrap();
            break;
        }
    }
    link.close().await;
    std::fs::copy(&at_kill, &state).unwrap();

    let (link, _sender, mut events) = start(s);
    tokio::time::sleep(Duration::from_millis(100)).await;
    let hb = frame(AUTOPILOT, &heartbeat(), Some((KEY, 0, now_signing())));
    autopilot.send(addr, &hb);
    autopilot.send(addr, &captured_stop);
    let got = events_for(&mut events, Duration::from_millis(400)).await;
    let stats = link.close().await;
    let replayed = got.iter().any(
        |e| matches!(e, LinkEvent::Message(r) if matches!(r.message, MavMessage::COMMAND_LONG(_))),
    );
    assert!(!replayed, "replayed after a SIGKILL and a restart: {got:?}");
    assert_eq!(stats.signing_refused, 1, "{stats:?}");
}

/// Item 5: a command addressed to mgmot whose id the dialect does not know (it cannot even
/// be decoded) is answered COMMAND_ACK MAV_RESULT_UNSUPPORTED, with its own id.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item5_unknown_commands_get_unsupported() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let (link, _sender, _events) = start(settings(format!("udpin:127.0.0.1:{port}")));
    let gcs = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    gcs.send(addr, &frame(AUTOPILOT, &heartbeat(), None)); // through the autopilot's route
                                                           // COMMAND_LONG with command 31999 (no such MAV_CMD), target (1, 191), raw.
    let known = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
        command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
        target_system: 1,
        target_component: 191,
        ..Default::default()
    });
    let mut raw = MAVLinkV2MessageRaw::new();
    raw.serialize_message(
        MavHeader {
            system_id: 255,
            component_id: 190,
            sequence: 0,
        },
        &known,
    );
    let len = usize::from(raw.payload_length());
    let b = raw.as_mut_slice();
    b[10 + 28..10 + 30].copy_from_slice(&31999u16.to_le_bytes());
    let crc = mavlink_core::calculate_crc(&b[1..10 + len], COMMAND_LONG_DATA::EXTRA_CRC);
    b[10 + len..12 + len].copy_from_slice(&crc.to_le_bytes());
    gcs.send(addr, raw.raw_bytes());
    let got = gcs.receive_for(Duration::from_millis(500));
    link.close().await;
    let acks: Vec<(u16, u8, u8, u8)> = got
        .iter()
        .filter(|(h, _, _, _)| h.component_id == 191)
        .map(|(_, _, p, _)| {
            let mut q = [0u8; 10];
            q[..p.len().min(10)].copy_from_slice(&p[..p.len().min(10)]);
            (u16::from_le_bytes([q[0], q[1]]), q[2], q[8], q[9])
        })
        .collect();
    assert!(
        acks.contains(&(31999, MavResult::MAV_RESULT_UNSUPPORTED as u8, 255, 190)),
        "{acks:?}"
    );
    // The ack arrived through the frame parser, which checks the CRC against the dialect:
    // the CRC was made again after the id was written in.
}

/// Item 9: `tcpout` with nobody listening does not end the link: it retries with back-off,
/// connects when the server comes up, and reconnects after the server drops it.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn item9_tcpout_retries_and_reconnects() {
    let port = {
        let l = std::net::TcpListener::bind("127.0.0.1:0").unwrap();
        l.local_addr().unwrap().port()
    };
    let (link, sender, _events) = start(settings(format!("tcpout:127.0.0.1:{port}")));
    let heartbeats = tokio::spawn(async move {
        for _ in 0..60 {
            sender.send(heartbeat());
            tokio::time::sleep(Duration::from_millis(100)).await;
        }
    });
    tokio::time::sleep(Duration::from_millis(800)).await;
    let listener = tokio::net::TcpListener::bind(("127.0.0.1", port))
        .await
        .unwrap();
    for round in 0..2 {
        let (mut s, _) = tokio::time::timeout(Duration::from_secs(5), listener.accept())
            .await
            .unwrap_or_else(|_| panic!("no connection in round {round}"))
            .unwrap();
        let mut buf = [0u8; 256];
        let n = tokio::time::timeout(
            Duration::from_secs(3),
            tokio::io::AsyncReadExt::read(&mut s, &mut buf),
        )
        .await
        .unwrap()
        .unwrap();
        let mut p = FrameParser::new();
        assert!(!p.push(&buf[..n]).is_empty(), "round {round}: no frame");
        drop(s); // the server drops the link: mgmot reconnects
    }
    heartbeats.abort();
    let stats = link.close().await;
    assert!(stats.connects >= 2, "{stats:?}");
}

/// Stream requests (items 9 and real-autopilot 2/3): nothing is asked before the autopilot
/// has been heard (a `udpin` request would be lost), every stream is asked for one request at
/// a time, again while it does not flow, and from scratch after the autopilot reboots.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn streams_are_requested_after_first_contact_and_after_a_reboot() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let mut s = settings(format!("udpin:127.0.0.1:{port}"));
    s.streams = vec![(GLOBAL_POSITION_INT_DATA::ID, 10.0)];
    let (link, _sender, _events) = start(s);
    let autopilot = Peer::new();
    tokio::time::sleep(Duration::from_millis(300)).await;
    let requests = |got: &[Got]| {
        got.iter()
            .filter(|(_, m, _, _)| {
                matches!(m, Some(MavMessage::COMMAND_LONG(c))
                    if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL
                        && c.param1 == GLOBAL_POSITION_INT_DATA::ID as f32)
            })
            .count()
    };
    autopilot.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    let got = autopilot.receive_for(Duration::from_millis(500));
    assert_eq!(requests(&got), 1, "asked once the autopilot spoke");
    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
        result: MavResult::MAV_RESULT_ACCEPTED,
        target_system: 1,
        target_component: 191,
        ..Default::default()
    });
    autopilot.send(addr, &frame(AUTOPILOT, &ack, None));
    // The stream flows for a while: no new request.
    let mut boot_ms = 10_000u32;
    let flow = |autopilot: &Peer, boot_ms: u32| {
        let mut p = position(500_000_000);
        if let MavMessage::GLOBAL_POSITION_INT(g) = &mut p {
            g.time_boot_ms = boot_ms;
        }
        autopilot.send(addr, &frame(AUTOPILOT, &p, None));
    };
    let mut asked = 0;
    for _ in 0..25 {
        boot_ms += 100;
        flow(&autopilot, boot_ms);
        asked += requests(&autopilot.receive_for(Duration::from_millis(100)));
    }
    assert_eq!(asked, 0, "asked again while the stream flowed");
    // Reboot: boot time back to 1 s and on from there: asked again as soon as the new
    // timeline held alone for half a second (a lone stamp near zero is no reboot).
    flow(&autopilot, 1000);
    assert_eq!(
        requests(&autopilot.receive_for(Duration::from_millis(100))),
        0,
        "one stamp near zero taken for a reboot"
    );
    let mut got = Vec::new();
    for k in 1..=6 {
        flow(&autopilot, 1000 + k * 100);
        got.extend(autopilot.receive_for(Duration::from_millis(100)));
    }
    got.extend(autopilot.receive_for(Duration::from_millis(300)));
    let stats = link.close().await;
    assert_eq!(
        requests(&got),
        1,
        "not asked again after the reboot: {stats:?}"
    );
    assert_eq!(stats.autopilot_restarts, 1, "{stats:?}");
}

/// Issue 39, item 5: a flood of 5,000 commands a second was answered at 2,000 replies a
/// second and logged line by line. Commands beyond a sender's budget are dropped unanswered
/// and counted; another sender's command still gets its answer.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_command_flood_is_answered_within_the_senders_budget() {
    use mgmot::mavlink::link::command_budget::{COMMANDS_PER_S, COMMAND_BURST};
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let (link, _sender, _events) = start(settings(format!("udpin:127.0.0.1:{port}")));
    let gcs = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    gcs.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    // An unknown command (id 31999) the link answers itself, from two senders.
    let unknown = |from: (u8, u8)| {
        let known = MavMessage::COMMAND_LONG(COMMAND_LONG_DATA {
            command: MavCmd::MAV_CMD_CAMERA_STOP_TRACKING,
            target_system: 1,
            target_component: 191,
            ..Default::default()
        });
        let mut raw = MAVLinkV2MessageRaw::new();
        raw.serialize_message(
            MavHeader {
                system_id: u32::from(from.0),
                component_id: from.1,
                sequence: 0,
            },
            &known,
        );
        let len = usize::from(raw.payload_length());
        let b = raw.as_mut_slice();
        b[10 + 28..10 + 30].copy_from_slice(&31999u16.to_le_bytes());
        let crc = mavlink_core::calculate_crc(&b[1..10 + len], COMMAND_LONG_DATA::EXTRA_CRC);
        b[10 + len..12 + len].copy_from_slice(&crc.to_le_bytes());
        raw.raw_bytes().to_vec()
    };
    let (flood, operator) = (unknown((255, 190)), unknown((254, 1)));
    let started = std::time::Instant::now();
    let mut sent = 0u64;
    // 5,000 a second for 2 s, the operator's one command in the middle.
    while started.elapsed() < Duration::from_secs(2) {
        for _ in 0..50 {
            gcs.send(addr, &flood);
            sent += 1;
        }
        if sent == 5_000 {
            gcs.send(addr, &operator);
        }
        tokio::time::sleep(Duration::from_millis(10)).await;
    }
    let elapsed = started.elapsed().as_secs_f64();
    let got = gcs.receive_for(Duration::from_millis(500));
    let stats = link.close().await;
    let acks_to = |to: (u8, u8)| {
        got.iter()
            .filter(|(h, _, p, _)| h.component_id == 191 && p.len() >= 10 && (p[8], p[9]) == to)
            .count() as f64
    };
    let budget = COMMAND_BURST + COMMANDS_PER_S * (elapsed + 0.5);
    assert!(sent >= 5_000, "sent only {sent}");
    assert!(
        acks_to((255, 190)) <= budget,
        "{} answers to {sent} flooding commands in {elapsed:.1} s (budget {budget})",
        acks_to((255, 190))
    );
    assert!(acks_to((255, 190)) >= COMMAND_BURST, "{stats:?}");
    assert_eq!(
        acks_to((254, 1)),
        1.0,
        "the operator's command was not answered"
    );
    assert!(
        stats.commands_over_budget as f64 >= sent as f64 - budget,
        "{stats:?}"
    );
}

/// Issue 39 item 6: ArduPilot forwards mgmot's TIMESYNC requests to its other links, and the
/// ground stations there answer (307 answers in 6 min on SITL); they also send requests of their
/// own. None of them is used, and none is worth a warning: they are counted, logged at debug.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn flight_day_6_timesync_from_a_ground_station_is_ignored_quietly() {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let mut s = settings(format!("udpin:127.0.0.1:{port}"));
    s.timesync_hz = 5.0;
    let (link, _sender, mut events) = start(s);
    let router = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    router.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    tokio::time::sleep(Duration::from_millis(100)).await;
    for k in 0..5i64 {
        let request = MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 0,
            ts1: 1_000_000 + k,
            ..Default::default()
        });
        let answer = MavMessage::TIMESYNC(TIMESYNC_DATA {
            tc1: 123_000_000,
            ts1: 2_000_000 + k,
            target_system: 1,
            target_component: 191,
        });
        router.send(addr, &frame(GCS, &request, None));
        router.send(addr, &frame(GCS, &answer, None));
    }
    let got = events_for(&mut events, Duration::from_millis(300)).await;
    let stats = link.close().await;
    assert!(
        !got.iter().any(|e| matches!(e, LinkEvent::TimeSync { .. })),
        "a ground station's TIMESYNC was used"
    );
    assert_eq!(
        stats.telemetry_from_others, 0,
        "a ground station's TIMESYNC counted (and warned) as spoofed telemetry: {stats:?}"
    );
    assert_eq!(stats.timesync_from_others, 10, "{stats:?}");
}

/// HEARTBEAT of an autopilot of type `autopilot`.
fn heartbeat_of(autopilot: MavAutopilot) -> MavMessage {
    MavMessage::HEARTBEAT(HEARTBEAT_DATA {
        autopilot,
        ..Default::default()
    })
}

/// Plays an autopilot of type `autopilot` for `d` (pose first, its HEARTBEAT only after
/// 600 ms, then at 1 Hz), answering every SET_MESSAGE_INTERVAL (MOUNT_ORIENTATION refused, as
/// ArduPilot does); returns the message ids mgmot asked for.
async fn stream_requests_of(autopilot_type: MavAutopilot, d: Duration) -> Vec<u32> {
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let mut s = settings(format!("udpin:127.0.0.1:{port}"));
    s.streams = vec![
        (GLOBAL_POSITION_INT_DATA::ID, 10.0),
        (MOUNT_ORIENTATION, 10.0),
    ];
    let (link, _sender, _events) = start(s);
    let autopilot = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    let started = Instant::now();
    let mut asked = Vec::new();
    let mut last_heartbeat: Option<Instant> = None;
    while started.elapsed() < d {
        if started.elapsed() >= Duration::from_millis(600)
            && last_heartbeat.is_none_or(|t| t.elapsed() >= Duration::from_secs(1))
        {
            autopilot.send(addr, &frame(AUTOPILOT, &heartbeat_of(autopilot_type), None));
            last_heartbeat = Some(Instant::now());
        }
        autopilot.send(addr, &frame(AUTOPILOT, &position(500_000_000), None));
        for (_, m, _, _) in autopilot.receive_for(Duration::from_millis(50)) {
            if let Some(MavMessage::COMMAND_LONG(c)) = m {
                if c.command == MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL {
                    let id = c.param1 as u32;
                    asked.push(id);
                    let result = if id == MOUNT_ORIENTATION {
                        MavResult::MAV_RESULT_DENIED
                    } else {
                        MavResult::MAV_RESULT_ACCEPTED
                    };
                    let ack = MavMessage::COMMAND_ACK(COMMAND_ACK_DATA {
                        command: MavCmd::MAV_CMD_SET_MESSAGE_INTERVAL,
                        result,
                        target_system: 1,
                        target_component: 191,
                        ..Default::default()
                    });
                    autopilot.send(addr, &frame(AUTOPILOT, &ack, None));
                }
            }
        }
    }
    link.close().await;
    asked
}

/// Issue 39 item 6: ArduPilot refuses MOUNT_ORIENTATION, and tells the operator's ground
/// station "No ap_message for mavlink id (265)" each time it is asked. Its HEARTBEAT says it
/// is ArduPilot: it is not asked (even when pose arrives before the first HEARTBEAT). Another
/// autopilot still is.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn flight_day_6_mount_orientation_is_not_asked_of_ardupilot() {
    let asked = stream_requests_of(
        MavAutopilot::MAV_AUTOPILOT_ARDUPILOTMEGA,
        Duration::from_millis(2500),
    )
    .await;
    assert!(
        asked.contains(&GLOBAL_POSITION_INT_DATA::ID),
        "the pose stream was not asked for: {asked:?}"
    );
    assert!(
        !asked.contains(&MOUNT_ORIENTATION),
        "ArduPilot was asked for MOUNT_ORIENTATION: {asked:?}"
    );
    let asked =
        stream_requests_of(MavAutopilot::MAV_AUTOPILOT_PX4, Duration::from_millis(2500)).await;
    assert!(
        asked.contains(&MOUNT_ORIENTATION),
        "another autopilot was not asked for MOUNT_ORIENTATION: {asked:?}"
    );
}

/// Issue 39 item 8: a notice longer than STATUSTEXT's 50 bytes reaches the ground station
/// whole ("recording stopped: Input/output error (os e" was all it saw): MAVLink 2's chunked
/// STATUSTEXT, reassembled here as QGroundControl and MAVProxy do.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn flight_day_8_long_notices_reach_the_ground_station_whole() {
    use mgmot::health::{Level, Notice};
    let port = free_udp_port();
    let addr: SocketAddr = ([127, 0, 0, 1], port).into();
    let (link, _inbox, outputs) =
        mgmot::mavlink::bridge::start(settings(format!("udpin:127.0.0.1:{port}")), false).unwrap();
    let gcs = Peer::new();
    tokio::time::sleep(Duration::from_millis(200)).await;
    gcs.send(addr, &frame(AUTOPILOT, &heartbeat(), None));
    tokio::time::sleep(Duration::from_millis(100)).await;
    let texts = [
        "mgmot: recording stopped: Input/output error (os error 5)".to_string(),
        "short".to_string(),
        "x".repeat(100),
        "é".repeat(40),
    ];
    for t in &texts {
        outputs.notice(&Notice::new(Level::Warning, t.clone()));
    }
    let got = gcs.receive_for(Duration::from_millis(400));
    link.close().await;
    let chunks: Vec<STATUSTEXT_DATA> = got
        .into_iter()
        .filter_map(|(_, m, _, _)| match m {
            Some(MavMessage::STATUSTEXT(s)) => Some(s),
            _ => None,
        })
        .collect();
    // Reassembly as the STATUSTEXT spec says: id 0 stands alone; chunks of one id in
    // chunk_seq order, the last one holding a NUL.
    let mut whole: Vec<String> = Vec::new();
    let mut pending: Vec<u8> = Vec::new();
    let mut pending_id = None;
    for c in &chunks {
        let bytes: [u8; 50] = c.text.into();
        let end = bytes.iter().position(|&b| b == 0).unwrap_or(50);
        if c.id == 0 {
            whole.push(String::from_utf8(bytes[..end].to_vec()).unwrap());
            continue;
        }
        if pending_id != Some(c.id) {
            assert!(pending.is_empty(), "chunks of two texts interleave");
            pending_id = Some(c.id);
            assert_eq!(c.chunk_seq, 0, "a text starts with chunk 0");
        }
        pending.extend_from_slice(&bytes[..end]);
        if end < 50 {
            whole.push(String::from_utf8(std::mem::take(&mut pending)).unwrap());
            pending_id = None;
        }
    }
    assert!(pending.is_empty(), "a text without its last chunk");
    assert_eq!(whole, texts);
    let mut ids: Vec<u16> = chunks.iter().map(|c| c.id).filter(|&i| i != 0).collect();
    ids.dedup();
    assert_eq!(ids.len(), 3, "one id per chunked text: {ids:?}");
    ids.sort_unstable();
    ids.dedup();
    assert_eq!(ids.len(), 3, "two texts share an id: {ids:?}");
}
