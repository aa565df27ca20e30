//! The UDP relay between the simulator (autopilot) and `mgmot run`, recording everything
//! mgmot sends.

use mavlink_core::{MavHeader, MavlinkReader, MavlinkVersion};
use mgmot::mavlink::dialect::MavMessage;
use std::net::UdpSocket;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

/// One message mgmot sent, with the datagram it came in.
#[derive(Clone)]
pub struct Sent {
    /// The whole datagram (for signature checks).
    pub bytes: Vec<u8>,
    /// Its MAVLink header.
    pub header: MavHeader,
    /// The decoded message (the project's dialect).
    pub msg: MavMessage,
}

/// The UDP link between the simulator and mgmot: the simulator sends to `listen_port`, the
/// relay forwards to mgmot's `udpin` port and mgmot's answers back to the simulator, and
/// records every message mgmot sends. `to_mgmot` is the relay's mgmot-side socket: what a
/// test sends from it reaches mgmot from the peer it answers (a `udpin` link answers its
/// latest peer).
pub struct Relay {
    /// Everything mgmot sent so far.
    pub sent: Arc<Mutex<Vec<Sent>>>,
    /// The port the simulator sends to.
    pub listen_port: u16,
    /// mgmot's `udpin` port.
    pub mgmot_port: u16,
    /// A clone of the socket that talks to mgmot.
    pub to_mgmot: UdpSocket,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

impl Relay {
    /// Starts relaying to mgmot at `127.0.0.1:mgmot_port`.
    pub fn start(mgmot_port: u16) -> Relay {
        Relay::start_teed(mgmot_port, None)
    }

    /// As [`Relay::start`], and also copies every datagram of both directions to
    /// `127.0.0.1:tee_port`, as mavlink-router copies everything to a ground station.
    pub fn start_teed(mgmot_port: u16, tee_port: Option<u16>) -> Relay {
        // One thread per direction, each blocking on its socket (the timeout only lets it see
        // `stop`): at 50 Hz per stream the simulator sends a few hundred datagrams a second,
        // and one thread polling both sockets in turn fell behind on a loaded machine.
        let up = UdpSocket::bind("127.0.0.1:0").unwrap();
        let down = UdpSocket::bind("127.0.0.1:0").unwrap();
        up.set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        down.set_read_timeout(Some(Duration::from_millis(50)))
            .unwrap();
        let listen_port = up.local_addr().unwrap().port();
        let to_mgmot = down.try_clone().unwrap();
        let sent = Arc::new(Mutex::new(Vec::new()));
        let stop = Arc::new(AtomicBool::new(false));
        let sim: Arc<Mutex<Option<std::net::SocketAddr>>> = Arc::new(Mutex::new(None));
        let upstream = {
            let (up, down, s, sim) = (
                up.try_clone().unwrap(),
                down.try_clone().unwrap(),
                stop.clone(),
                sim.clone(),
            );
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !s.load(Ordering::Relaxed) {
                    if let Ok((n, from)) = up.recv_from(&mut buf) {
                        *sim.lock().unwrap() = Some(from);
                        let _ = down.send_to(&buf[..n], ("127.0.0.1", mgmot_port));
                        if let Some(tee) = tee_port {
                            let _ = down.send_to(&buf[..n], ("127.0.0.1", tee));
                        }
                    }
                }
            })
        };
        let downstream = {
            let (log, s) = (sent.clone(), stop.clone());
            std::thread::spawn(move || {
                let mut buf = [0u8; 65536];
                while !s.load(Ordering::Relaxed) {
                    if let Ok(n) = down.recv(&mut buf) {
                        let to_sim = *sim.lock().unwrap();
                        if let Some(to_sim) = to_sim {
                            let _ = up.send_to(&buf[..n], to_sim);
                        }
                        if let Some(tee) = tee_port {
                            let _ = up.send_to(&buf[..n], ("127.0.0.1", tee));
                        }
                        let mut reader = MavlinkReader::new(&buf[..n]);
                        while let Ok((header, msg)) =
                            reader.read_message::<MavMessage>(MavlinkVersion::V2)
                        {
                            log.lock().unwrap().push(Sent {
                                bytes: buf[..n].to_vec(),
                                header,
                                msg,
                            });
                        }
                    }
                }
            })
        };
        Relay {
            sent,
            listen_port,
            mgmot_port,
            to_mgmot,
            stop,
            threads: vec![upstream, downstream],
        }
    }

    /// The texts of the STATUSTEXT messages mgmot sent so far (chunks as sent).
    pub fn statustexts(&self) -> Vec<String> {
        self.sent
            .lock()
            .unwrap()
            .iter()
            .filter_map(|s| match &s.msg {
                MavMessage::STATUSTEXT(t) => t.text.to_str().ok().map(str::to_owned),
                _ => None,
            })
            .collect()
    }

    /// How many messages mgmot has sent so far (a position to wait from).
    pub fn mark(&self) -> usize {
        self.sent.lock().unwrap().len()
    }

    /// What mgmot sent from position `from` on.
    pub fn since(&self, from: usize) -> Vec<Sent> {
        self.sent.lock().unwrap()[from..].to_vec()
    }

    /// The first message from position `from` on that `pred` accepts, waiting up to `limit`.
    pub fn wait_for(
        &self,
        from: usize,
        limit: Duration,
        mut pred: impl FnMut(&MavMessage) -> bool,
    ) -> Option<(usize, Sent)> {
        let start = Instant::now();
        let mut next = from;
        while start.elapsed() < limit {
            {
                let sent = self.sent.lock().unwrap();
                for (i, s) in sent.iter().enumerate().skip(next) {
                    if pred(&s.msg) {
                        return Some((i, s.clone()));
                    }
                }
                next = sent.len();
            }
            std::thread::sleep(Duration::from_millis(5));
        }
        None
    }

    /// Stops relaying; everything mgmot sent.
    pub fn finish(mut self) -> Vec<Sent> {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            t.join().unwrap();
        }
        std::mem::take(&mut *self.sent.lock().unwrap())
    }
}

impl Drop for Relay {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
