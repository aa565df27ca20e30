//! `[outputs.cot]`: `mgmot run` against the real `mgmot-sim` on loopback, sending Cursor-on-Target
//! events to a TCP server (which drops the first connection to make mgmot reconnect) and to
//! the TAK situational-awareness multicast group on the loopback interface. Every event is
//! checked against the CoT event schema by `scripts/cot_check.py` (lxml), and against the
//! simulator's truth: each track event lies at a true object of its class.

use crate::common;

use common::{
    distance_m, free_udp_port, mgmot_run, read_truth, require_python, run_config, Relay, Scenario,
    TestDir, Truth,
};
use mgmot::config::{CotConfig, FramesConfig};
use std::collections::{BTreeMap, BTreeSet};
use std::io::Read;
use std::net::{Ipv4Addr, TcpListener, UdpSocket};
use std::path::Path;
use std::process::Command;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// One event as the tests read it.
#[derive(Debug, Clone)]
struct Event {
    xml: String,
    uid: String,
    cot_type: String,
    time: String,
    stale: String,
    lat: f64,
    lon: f64,
    ce: f64,
}

fn attr(xml: &str, element: &str, name: &str) -> Option<String> {
    let start = xml.find(&format!("<{element} "))?;
    let rest = &xml[start..];
    let rest = &rest[..rest.find('>')?];
    let key = format!(" {name}=\"");
    let at = rest.find(&key)? + key.len();
    Some(rest[at..at + rest[at..].find('"')?].to_owned())
}

fn parse(xml: &str) -> Event {
    let get = |e: &str, a: &str| attr(xml, e, a).unwrap_or_else(|| panic!("no {e}@{a} in {xml}"));
    let num = |e: &str, a: &str| get(e, a).parse::<f64>().expect("a number");
    Event {
        xml: xml.to_owned(),
        uid: get("event", "uid"),
        cot_type: get("event", "type"),
        time: get("event", "time"),
        stale: get("event", "stale"),
        lat: num("point", "lat"),
        lon: num("point", "lon"),
        ce: num("point", "ce"),
    }
}

fn split(stream: &str) -> Vec<String> {
    stream
        .split_inclusive("</event>")
        .map(str::trim)
        .filter(|s| !s.is_empty())
        .map(str::to_owned)
        .collect()
}

/// Runs `cot_check.py` on the events; panics with its report when any fails.
pub(crate) fn schema_check(dir: &TestDir, name: &str, events: &[String]) -> String {
    require_python("runtime_cot", &["lxml"]);
    let path = dir.join(name);
    std::fs::write(&path, events.concat()).expect("write the events");
    let out = Command::new("python3")
        .arg(common::repo_file("scripts/cot_check.py"))
        .arg(&path)
        .output()
        .expect("run python3");
    let report = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        out.status.success(),
        "CoT events fail the schema check: {report}"
    );
    report
}

/// The class of a track event (`<mgmot class=...>`), if it is one.
fn class_of(e: &Event) -> Option<String> {
    attr(&e.xml, "mgmot", "class").filter(|_| attr(&e.xml, "mgmot", "track_id").is_some())
}

/// Every live track event lies within `limit_m` of a true object of its class at some time of
/// the run (the objects drift slowly; the event's time is UTC, not the simulator's).
fn assert_at_true_objects(events: &[Event], truth: &[Truth], limit_m: f64) -> usize {
    let mut checked = 0;
    for e in events.iter().filter(|e| e.time != e.stale) {
        let Some(class) = class_of(e) else { continue };
        let class = if class == "lifebuoy" {
            "life_saving_appliance".to_owned()
        } else {
            class
        };
        let nearest = truth
            .iter()
            .filter(|g| g.class == class)
            .map(|g| distance_m((e.lat, e.lon), (g.lat, g.lon)))
            .fold(f64::INFINITY, f64::min);
        assert!(
            nearest < limit_m,
            "event {} is {nearest:.1} m from every true {class}",
            e.xml
        );
        assert!(e.ce > 0.0 && e.ce < 50.0, "ce {} in {}", e.ce, e.xml);
        checked += 1;
    }
    checked
}

/// `calm_baseline` for `seconds` at 640x360 (the replay detector does not look at pixels).
fn calm(seconds: f64) -> Scenario {
    Scenario::new("calm_baseline", seconds).size(640, 360)
}

/// A scenario run with the replay detector and `cot` as the CoT output, in lockstep or in real
/// time; returns mgmot's stats and the truth. A test whose output waits on the wall clock (a
/// reconnection's back-off) runs in real time: in lockstep a fast machine plays the whole
/// scenario within one back-off, and what it checks depends on the machine's speed.
fn run_with_cot(
    dir: &TestDir,
    cot: CotConfig,
    scenario: &Scenario,
    realtime: bool,
) -> (serde_json::Value, Vec<Truth>) {
    scenario.detections(&dir.join("dets.json"));
    let port = free_udp_port();
    let mut c = run_config(
        &format!("udpin:127.0.0.1:{port}"),
        &dir.join("frames.sock"),
        &dir.join("dets.json"),
    );
    if let FramesConfig::Sim {
        wait_for_detector, ..
    } = &mut c.frames
    {
        *wait_for_detector = true;
    }
    c.outputs.cot = cot;
    let config = dir.write_config("run.toml", &c);
    let tap = Relay::start(port);
    let mut sim = scenario
        .run(realtime, tap.listen_port, &dir.join("frames.sock"))
        .arg("--truth-out")
        .arg(dir.join("truth"))
        .spawn();
    let stats_path = dir.join("stats.json");
    let mut mgmot = mgmot_run(&config, Some(&stats_path)).spawn_logged(dir.join("mgmot.log"));
    let status = mgmot.wait_or_fail(Duration::from_secs(300));
    let _ = sim.wait_or_fail(Duration::from_secs(30));
    drop(tap.finish());
    assert!(status.success(), "mgmot run failed: {}", mgmot.log());
    let stats: serde_json::Value = std::fs::read_to_string(&stats_path)
        .ok()
        .and_then(|s| serde_json::from_str(&s).ok())
        .unwrap_or(serde_json::Value::Null);
    (stats, read_truth(&dir.join("truth/world.csv")))
}

/// TCP to a server that drops the first connection after a few events: mgmot reconnects,
/// starts each connection with its identity (the vehicle, stale at once), keeps every uid
/// across the two connections, and the events pass the schema and lie at true objects.
#[test]
fn tcp_events_pass_the_schema_lie_at_true_objects_and_survive_a_dropped_connection() {
    let dir = TestDir::new();
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind a TCP port");
    let server_port = listener.local_addr().expect("its address").port();
    let connections: Arc<Mutex<Vec<String>>> = Arc::default();
    let server = {
        let connections = connections.clone();
        std::thread::spawn(move || {
            for (n, stream) in listener.incoming().enumerate() {
                let Ok(mut stream) = stream else { return };
                let _ = stream.set_read_timeout(Some(Duration::from_millis(200)));
                let index = {
                    let mut c = connections.lock().expect("lock");
                    c.push(String::new());
                    c.len() - 1
                };
                let mut buf = [0u8; 8192];
                let started = Instant::now();
                loop {
                    match stream.read(&mut buf) {
                        Ok(0) => break,
                        Ok(k) => {
                            let mut c = connections.lock().expect("lock");
                            c[index].push_str(&String::from_utf8_lossy(&buf[..k]));
                            // The first connection is dropped after its fourth track event.
                            if n == 0 && c[index].matches(" track_id=").count() >= 4 {
                                break;
                            }
                        }
                        Err(_) if started.elapsed() < Duration::from_secs(300) => {}
                        Err(_) => break,
                    }
                }
                if n >= 1 {
                    return;
                }
            }
        })
    };
    let cot = CotConfig {
        enabled: true,
        url: format!("tcp://127.0.0.1:{server_port}"),
        rate_hz: 2.0,
        ..CotConfig::default()
    };
    let (stats, truth) = run_with_cot(&dir, cot, &calm(12.0), true);
    // mgmot closed the second connection on exit: the server thread ends.
    let _ = server.join();
    let connections = connections.lock().expect("lock").clone();
    assert!(
        connections.len() >= 2,
        "mgmot did not reconnect after the drop: {} connection(s); stats {stats}",
        connections.len()
    );
    let mut all = Vec::new();
    let mut vehicle_uid = None;
    for (i, c) in connections.iter().enumerate() {
        let events: Vec<Event> = split(c).iter().map(|x| parse(x)).collect();
        let first = events
            .first()
            .unwrap_or_else(|| panic!("connection {i} got no event"));
        assert_eq!(
            first.cot_type, "a-f-A-M-H-Q",
            "connection {i} starts with the vehicle: {}",
            first.xml
        );
        assert_eq!(
            first.time, first.stale,
            "the identity is stale at once: {}",
            first.xml
        );
        assert_eq!(vehicle_uid.get_or_insert(first.uid.clone()), &first.uid);
        all.extend(events);
    }
    let report = schema_check(
        &dir,
        "tcp.xml",
        &all.iter().map(|e| e.xml.clone()).collect::<Vec<_>>(),
    );
    let checked = assert_at_true_objects(&all, &truth, 5.0);
    assert!(checked >= 10, "only {checked} track events; {report}");
    // One uid per track id, the same on both connections, each with one type.
    let mut uid_types: BTreeMap<String, BTreeSet<String>> = BTreeMap::new();
    for e in all.iter().filter(|e| class_of(e).is_some()) {
        uid_types
            .entry(e.uid.clone())
            .or_default()
            .insert(e.cot_type.clone());
        let track = attr(&e.xml, "mgmot", "track_id").expect("a track id");
        assert!(
            e.uid.ends_with(&format!(".{track}")),
            "uid {} for track {track}",
            e.uid
        );
        assert!(
            e.uid.starts_with(vehicle_uid.as_deref().unwrap_or("")),
            "{}",
            e.uid
        );
    }
    assert!(uid_types.values().all(|t| t.len() == 1), "{uid_types:?}");
    let second: BTreeSet<String> = split(&connections[1])
        .iter()
        .map(|x| parse(x).uid)
        .collect();
    let first: BTreeSet<String> = split(&connections[0])
        .iter()
        .map(|x| parse(x).uid)
        .collect();
    assert!(
        first.iter().filter(|u| second.contains(*u)).count() >= 2,
        "the uids continue on the new connection: {first:?} / {second:?}"
    );
    let s = &stats["cot"];
    assert!(s["connects"].as_u64() >= Some(2), "{stats}");
    assert_eq!(s["dropped"].as_u64(), Some(0), "{stats}");
    eprintln!("runtime_cot tcp: {report}; stats {s}");
}

/// UDP to the TAK situational-awareness multicast group on the loopback interface (as ATAK
/// on the same machine would join it): the events arrive as one datagram each and pass.
#[test]
fn multicast_events_reach_a_member_of_the_group_on_loopback() {
    let dir = TestDir::new();
    let group = Ipv4Addr::new(239, 2, 3, 1);
    let receiver = UdpSocket::bind((Ipv4Addr::UNSPECIFIED, 0)).expect("bind");
    let port = receiver.local_addr().expect("address").port();
    receiver
        .join_multicast_v4(&group, &Ipv4Addr::LOCALHOST)
        .expect("join 239.2.3.1 on 127.0.0.1");
    receiver
        .set_read_timeout(Some(Duration::from_millis(200)))
        .expect("timeout");
    let received: Arc<Mutex<Vec<String>>> = Arc::default();
    let stop = Arc::new(std::sync::atomic::AtomicBool::new(false));
    let thread = {
        let (received, stop) = (received.clone(), stop.clone());
        std::thread::spawn(move || {
            let mut buf = vec![0u8; 65536];
            while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                if let Ok((n, _)) = receiver.recv_from(&mut buf) {
                    received
                        .lock()
                        .expect("lock")
                        .push(String::from_utf8_lossy(&buf[..n]).into_owned());
                }
            }
        })
    };
    let cot = CotConfig {
        enabled: true,
        url: format!("udp://239.2.3.1:{port}"),
        multicast_interface: "127.0.0.1".into(),
        ..CotConfig::default()
    };
    let (stats, truth) = run_with_cot(&dir, cot, &calm(8.0), false);
    std::thread::sleep(Duration::from_millis(300));
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let _ = thread.join();
    let datagrams = received.lock().expect("lock").clone();
    let sent = stats["cot"]["sent"].as_u64().unwrap_or(0);
    assert!(sent > 0, "nothing sent: {stats}");
    assert_eq!(
        datagrams.len() as u64,
        sent,
        "every datagram arrived (loopback): {stats}"
    );
    assert!(
        datagrams.iter().all(|d| split(d).len() == 1),
        "one event per datagram"
    );
    let report = schema_check(&dir, "udp.xml", &datagrams);
    let events: Vec<Event> = datagrams.iter().map(|d| parse(d)).collect();
    let checked = assert_at_true_objects(&events, &truth, 5.0);
    assert!(checked >= 5, "only {checked} track events; {report}");
    assert!(
        events
            .iter()
            .any(|e| e.cot_type == "a-f-A-M-H-Q" && e.time != e.stale),
        "the vehicle is sent with its position"
    );
    eprintln!("runtime_cot multicast: {report}");
}

/// A TCP server that is not there: mgmot keeps tracking at full speed (the CoT task retries
/// in the background), and says so in its log and stats.
#[test]
fn an_unreachable_server_never_holds_up_tracking() {
    let dir = TestDir::new();
    // A port nobody listens on.
    let port = TcpListener::bind("127.0.0.1:0")
        .and_then(|l| l.local_addr())
        .expect("a free port")
        .port();
    let cot = CotConfig {
        enabled: true,
        url: format!("tcp://127.0.0.1:{port}"),
        ..CotConfig::default()
    };
    let (stats, _) = run_with_cot(&dir, cot, &calm(6.0), false);
    let log = std::fs::read_to_string(dir.join("mgmot.log")).unwrap_or_default();
    assert!(log.contains("CoT: cannot reach the server"), "{log}");
    assert!(stats["track_messages"].as_u64() > Some(0), "{stats}");
    assert!(stats["cot"]["errors"].as_u64() > Some(0), "{stats}");
    assert_eq!(stats["cot"]["sent"].as_u64(), Some(0), "{stats}");
    assert!(stats["cot"]["events"].as_u64() > Some(0), "{stats}");
    // Lockstep: every frame the simulator sent was processed, none dropped.
    assert_eq!(stats["frames_dropped"].as_u64(), Some(0), "{stats}");
    assert_eq!(
        stats["frames_processed"], stats["frames_captured"],
        "{stats}"
    );
}

/// Makes a CA, a server certificate for `tak.test` and a client certificate with openssl;
/// returns (ca.pem, server.pem, server.key, client.pem, client.key).
fn make_certs(dir: &TestDir, name: &str) -> [std::path::PathBuf; 5] {
    let p = |f: &str| dir.join(format!("{name}-{f}"));
    let run = |args: &[&str]| {
        let o = Command::new("openssl")
            .args(args)
            .output()
            .unwrap_or_else(|e| {
                common::missing_tool("runtime_cot (TLS)", &format!("openssl ({e})"))
            });
        assert!(
            o.status.success(),
            "openssl {args:?}: {}",
            String::from_utf8_lossy(&o.stderr)
        );
    };
    let s = |p: &std::path::PathBuf| p.display().to_string();
    let ec = [
        "-newkey",
        "ec",
        "-pkeyopt",
        "ec_paramgen_curve:P-256",
        "-nodes",
    ];
    let mut ca = vec!["req", "-x509"];
    ca.extend(ec);
    let (ca_key, ca_pem) = (s(&p("ca.key")), s(&p("ca.pem")));
    ca.extend([
        "-keyout",
        &ca_key,
        "-out",
        &ca_pem,
        "-days",
        "2",
        "-subj",
        "/CN=mgmot test CA",
    ]);
    run(&ca);
    for (who, ext) in [
        (
            "server",
            "subjectAltName=DNS:tak.test\nextendedKeyUsage=serverAuth\n",
        ),
        ("client", "extendedKeyUsage=clientAuth\n"),
    ] {
        let (key, csr, pem, extfile) = (
            s(&p(&format!("{who}.key"))),
            s(&p(&format!("{who}.csr"))),
            s(&p(&format!("{who}.pem"))),
            s(&p(&format!("{who}.ext"))),
        );
        std::fs::write(&extfile, ext).expect("write the extensions");
        let mut req = vec!["req"];
        req.extend(ec);
        let subj = format!("/CN={who}");
        req.extend(["-keyout", &key, "-out", &csr, "-subj", &subj]);
        run(&req);
        run(&[
            "x509",
            "-req",
            "-in",
            &csr,
            "-CA",
            &ca_pem,
            "-CAkey",
            &ca_key,
            "-CAcreateserial",
            "-out",
            &pem,
            "-days",
            "2",
            "-extfile",
            &extfile,
        ]);
    }
    [
        p("ca.pem"),
        p("server.pem"),
        p("server.key"),
        p("client.pem"),
        p("client.key"),
    ]
}

/// A TLS server on loopback that requires a client certificate signed by `ca` and records
/// what each connection sends (one thread per connection, until the run ends).
fn tls_server(ca: &Path, cert: &Path, key: &Path) -> (u16, Arc<Mutex<Vec<String>>>) {
    use rustls::pki_types::pem::PemObject;
    use rustls::pki_types::{CertificateDer, PrivateKeyDer};
    use tokio_rustls::rustls;
    #[allow(deprecated)]
    let provider = Arc::new(rustls::crypto::ring::default_provider());
    let mut roots = rustls::RootCertStore::empty();
    for c in CertificateDer::pem_file_iter(ca).expect("the CA") {
        roots.add(c.expect("a CA certificate")).expect("add the CA");
    }
    let verifier = rustls::server::WebPkiClientVerifier::builder_with_provider(
        Arc::new(roots),
        provider.clone(),
    )
    .build()
    .expect("a client verifier");
    let chain: Vec<CertificateDer<'static>> = CertificateDer::pem_file_iter(cert)
        .expect("the server certificate")
        .map(|c| c.expect("a certificate"))
        .collect();
    let config = Arc::new(
        rustls::ServerConfig::builder_with_provider(provider)
            .with_safe_default_protocol_versions()
            .expect("TLS versions")
            .with_client_cert_verifier(verifier)
            .with_single_cert(chain, PrivateKeyDer::from_pem_file(key).expect("the key"))
            .expect("the server configuration"),
    );
    let listener = TcpListener::bind("127.0.0.1:0").expect("bind");
    let port = listener.local_addr().expect("address").port();
    let received: Arc<Mutex<Vec<String>>> = Arc::default();
    let r = received.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let Ok(stream) = stream else { return };
            let (config, r) = (config.clone(), r.clone());
            std::thread::spawn(move || {
                let _ = stream.set_read_timeout(Some(Duration::from_secs(60)));
                let Ok(conn) = rustls::ServerConnection::new(config) else {
                    return;
                };
                let mut tls = rustls::StreamOwned::new(conn, stream);
                let index = {
                    let mut v = r.lock().expect("lock");
                    v.push(String::new());
                    v.len() - 1
                };
                let mut buf = [0u8; 8192];
                while let Ok(n) = tls.read(&mut buf) {
                    if n == 0 {
                        break;
                    }
                    r.lock().expect("lock")[index].push_str(&String::from_utf8_lossy(&buf[..n]));
                }
            });
        }
    });
    (port, received)
}

/// TLS with a client certificate to a server whose certificate names another host
/// (`verify_hostname = false`): the events arrive and pass the schema. With a CA that did not
/// sign the server's certificate, nothing is sent and the handshake failure is logged.
#[test]
fn tls_with_a_client_certificate_and_a_server_of_another_ca() {
    let dir = TestDir::new();
    let [ca, server_pem, server_key, client_pem, client_key] = make_certs(&dir, "good");
    let (port, received) = tls_server(&ca, &server_pem, &server_key);
    let tls = mgmot::config::CotTlsConfig {
        cert: client_pem.clone(),
        key: client_key.clone(),
        ca: ca.clone(),
        verify_hostname: false,
    };
    let cot = CotConfig {
        enabled: true,
        url: format!("tls://127.0.0.1:{port}"),
        tls: Some(tls.clone()),
        ..CotConfig::default()
    };
    let (stats, truth) = run_with_cot(&dir, cot, &calm(8.0), false);
    std::thread::sleep(Duration::from_millis(300));
    let streams = received.lock().expect("lock").clone();
    let events: Vec<String> = streams.iter().flat_map(|s| split(s)).collect();
    assert!(!events.is_empty(), "nothing arrived over TLS: {stats}");
    let report = schema_check(&dir, "tls.xml", &events);
    let parsed: Vec<Event> = events.iter().map(|x| parse(x)).collect();
    assert!(
        assert_at_true_objects(&parsed, &truth, 5.0) >= 3,
        "{report}"
    );
    // Every event mgmot sent arrived, after the identity.
    assert_eq!(
        stats["cot"]["sent"].as_u64(),
        Some(events.len() as u64 - 1),
        "{stats}"
    );

    // The same client against a CA that did not sign the server: refused.
    let other = TestDir::new();
    let [other_ca, ..] = make_certs(&other, "other");
    let cot = CotConfig {
        enabled: true,
        url: format!("tls://127.0.0.1:{port}"),
        tls: Some(mgmot::config::CotTlsConfig {
            ca: other_ca,
            ..tls
        }),
        ..CotConfig::default()
    };
    let before = received
        .lock()
        .expect("lock")
        .iter()
        .map(|s| split(s).len())
        .sum::<usize>();
    let (stats, _) = run_with_cot(&other, cot, &calm(4.0), false);
    let log = std::fs::read_to_string(other.join("mgmot.log")).unwrap_or_default();
    assert!(log.contains("TLS handshake"), "{log}");
    assert_eq!(stats["cot"]["sent"].as_u64(), Some(0), "{stats}");
    let after = received
        .lock()
        .expect("lock")
        .iter()
        .map(|s| split(s).len())
        .sum::<usize>();
    assert_eq!(before, after, "nothing reached the server");
}
