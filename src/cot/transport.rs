//! Sending CoT events: UDP (unicast or multicast), a TCP stream to a TAK server, or TLS with a
//! client certificate. One task owns the connection; the frame path only queues events
//! ([`CotOutput::send`] never waits). A lost server is reached again with a doubling wait;
//! while it is away, only the latest event of each uid is kept, and those are sent first
//! when it is back (a map wants where things are now, not where they were).

use super::publisher::CotMessage;
use super::tls;
use crate::config::{CotEndpoint, CotSettings};
use std::collections::HashMap;
use std::net::{Ipv4Addr, SocketAddr};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Duration;
use tokio::io::{AsyncRead, AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpStream, UdpSocket};
use tokio::sync::mpsc;

/// How long a connection attempt or one write may take before the server counts as lost.
const IO_TIMEOUT: Duration = Duration::from_secs(5);
/// The first wait after a failed attempt.
const FIRST_BACKOFF: Duration = Duration::from_millis(500);

/// Counters of the CoT output (shared with the task).
#[derive(Debug, Default)]
pub struct CotStats {
    /// Events queued for the task.
    pub queued: AtomicU64,
    /// Events handed to the socket.
    pub sent: AtomicU64,
    /// Events replaced by a newer event of the same uid while the server was away.
    pub replaced: AtomicU64,
    /// Events dropped because the queue was full (the task was stuck longer than the queue).
    pub dropped: AtomicU64,
    /// UDP datagrams the socket refused (not retried: the next event of the track follows).
    pub failed: AtomicU64,
    /// Connections made (TCP/TLS), or 1 once the UDP socket is open.
    pub connects: AtomicU64,
    /// Failed connection attempts and writes.
    pub errors: AtomicU64,
    /// The task has ended (after [`CotOutput::close`]: the connection closed cleanly).
    pub closed: std::sync::atomic::AtomicBool,
}

/// Makes the event a stream connection starts with: a TAK server takes the first event of a
/// connection as the client's identity (and does not forward it).
pub type IdentityFn = Box<dyn Fn() -> CotMessage + Send + Sync>;

/// The frame path's handle on the CoT output.
#[derive(Debug, Clone)]
pub struct CotOutput {
    tx: mpsc::Sender<CotMessage>,
    stats: Arc<CotStats>,
}

impl CotOutput {
    /// Starts the sending task on the current tokio runtime.
    pub fn spawn(settings: &CotSettings, identity: IdentityFn) -> Self {
        let (tx, rx) = mpsc::channel(settings.queue);
        let stats = Arc::new(CotStats::default());
        let task = Task {
            endpoint: settings.endpoint.clone(),
            reconnect_max: settings.reconnect_max,
            stats: stats.clone(),
            identity,
            pending: Pending::default(),
        };
        tokio::spawn(task.run(rx));
        Self { tx, stats }
    }

    /// Queues an event; never waits. When the queue is full the event is dropped and counted.
    pub fn send(&self, m: CotMessage) {
        if self.tx.try_send(m).is_ok() {
            self.stats.queued.fetch_add(1, Ordering::Relaxed);
        } else {
            let n = self.stats.dropped.fetch_add(1, Ordering::Relaxed);
            if n.is_power_of_two() {
                tracing::warn!(
                    dropped = n + 1,
                    "CoT: the send queue is full; events are being dropped"
                );
            }
        }
    }

    /// Waits (blocking, on a thread that is not the runtime's) until every queued event has
    /// been sent or replaced by a newer one, or `limit` passed; returns how many are unsent.
    /// For the end of a run, so the last events reach the map.
    pub fn flush(&self, limit: Duration) -> u64 {
        let deadline = std::time::Instant::now() + limit;
        loop {
            let s = &self.stats;
            let settled = s.sent.load(Ordering::Relaxed)
                + s.replaced.load(Ordering::Relaxed)
                + s.failed.load(Ordering::Relaxed);
            let unsent = s.queued.load(Ordering::Relaxed).saturating_sub(settled);
            if unsent == 0 || std::time::Instant::now() >= deadline {
                return unsent;
            }
            std::thread::sleep(Duration::from_millis(10));
        }
    }

    /// Ends the output at the end of a run (blocking, on a thread that is not the runtime's):
    /// waits up to `limit` for the queued events to be sent ([`CotOutput::flush`]), then has
    /// the task close the connection cleanly, so the server reads every event before the end
    /// of the stream (an abrupt close with unread data makes the kernel reset the connection,
    /// and the server can lose what it had not read yet). Returns how many events were not
    /// sent.
    pub fn close(self, limit: Duration) -> u64 {
        let unsent = self.flush(limit);
        let stats = self.stats.clone();
        drop(self.tx);
        let deadline = std::time::Instant::now() + limit;
        while !stats.closed.load(Ordering::Relaxed) && std::time::Instant::now() < deadline {
            std::thread::sleep(Duration::from_millis(10));
        }
        unsent
    }

    /// The counters, shared (they outlive [`CotOutput::close`]).
    pub fn shared_stats(&self) -> Arc<CotStats> {
        self.stats.clone()
    }

    /// The counters.
    pub fn stats(&self) -> &CotStats {
        &self.stats
    }
}

/// The latest event of each uid, in the order the uids first came.
#[derive(Debug, Default)]
struct Pending {
    order: Vec<Arc<str>>,
    latest: HashMap<Arc<str>, CotMessage>,
}

impl Pending {
    /// Keeps `m`, replacing an older event of its uid; returns whether one was replaced.
    fn put(&mut self, m: CotMessage) -> bool {
        match self.latest.insert(m.uid.clone(), m.clone()) {
            Some(_) => true,
            None => {
                self.order.push(m.uid);
                false
            }
        }
    }

    fn take(&mut self) -> Vec<CotMessage> {
        let mut latest = std::mem::take(&mut self.latest);
        std::mem::take(&mut self.order)
            .into_iter()
            .filter_map(|uid| latest.remove(&uid))
            .collect()
    }
}

/// A connected byte stream (TCP or TLS).
trait Stream: AsyncRead + AsyncWrite + Unpin + Send {}
impl<T: AsyncRead + AsyncWrite + Unpin + Send> Stream for T {}

struct Task {
    endpoint: CotEndpoint,
    reconnect_max: Duration,
    stats: Arc<CotStats>,
    identity: IdentityFn,
    pending: Pending,
}

impl Task {
    async fn run(mut self, mut rx: mpsc::Receiver<CotMessage>) {
        self.run_endpoint(&mut rx).await;
        self.stats.closed.store(true, Ordering::Relaxed);
    }

    async fn run_endpoint(&mut self, rx: &mut mpsc::Receiver<CotMessage>) {
        match self.endpoint.clone() {
            CotEndpoint::Udp {
                host,
                port,
                multicast_interface,
                multicast_ttl,
            } => {
                self.run_udp(rx, &host, port, multicast_interface, multicast_ttl)
                    .await
            }
            _ => self.run_stream(rx).await,
        }
    }

    /// Waits `wait` while keeping the latest event of each uid; `false` when the output is
    /// closed (the runtime is stopping).
    async fn hold(&mut self, rx: &mut mpsc::Receiver<CotMessage>, wait: Duration) -> bool {
        let deadline = tokio::time::Instant::now() + wait;
        loop {
            tokio::select! {
                _ = tokio::time::sleep_until(deadline) => return true,
                m = rx.recv() => match m {
                    Some(m) => {
                        if self.pending.put(m) {
                            self.stats.replaced.fetch_add(1, Ordering::Relaxed);
                        }
                    }
                    None => return false,
                },
            }
        }
    }

    async fn run_udp(
        &mut self,
        rx: &mut mpsc::Receiver<CotMessage>,
        host: &str,
        port: u16,
        interface: Option<Ipv4Addr>,
        ttl: u32,
    ) {
        let mut backoff = FIRST_BACKOFF;
        let (socket, to) = loop {
            match open_udp(host, port, interface, ttl).await {
                Ok(s) => break s,
                Err(e) => {
                    self.stats.errors.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(
                        endpoint = %self.endpoint,
                        error = %e,
                        retry_s = backoff.as_secs_f64(),
                        "CoT: cannot open the UDP socket"
                    );
                    if !self.hold(rx, backoff).await {
                        return;
                    }
                    backoff = (backoff * 2).min(self.reconnect_max);
                }
            }
        };
        self.stats.connects.fetch_add(1, Ordering::Relaxed);
        tracing::info!(endpoint = %self.endpoint, "CoT: sending events over UDP");
        let mut queued = self.pending.take().into_iter();
        loop {
            let m = match queued.next() {
                Some(m) => m,
                None => match rx.recv().await {
                    Some(m) => m,
                    None => return,
                },
            };
            match socket.send_to(m.xml.as_bytes(), to).await {
                Ok(_) => {
                    self.stats.sent.fetch_add(1, Ordering::Relaxed);
                }
                Err(e) => {
                    self.stats.failed.fetch_add(1, Ordering::Relaxed);
                    let n = self.stats.errors.fetch_add(1, Ordering::Relaxed);
                    if n.is_power_of_two() {
                        tracing::warn!(endpoint = %self.endpoint, error = %e, errors = n + 1, "CoT: a UDP send failed");
                    }
                }
            }
        }
    }

    async fn run_stream(&mut self, rx: &mut mpsc::Receiver<CotMessage>) {
        let mut backoff = FIRST_BACKOFF;
        let mut failures = 0u64;
        loop {
            let stream = tokio::time::timeout(IO_TIMEOUT, connect(&self.endpoint)).await;
            let stream = match stream {
                Ok(Ok(s)) => s,
                Ok(Err(e)) => {
                    self.failed(&mut failures, &e, backoff);
                    if !self.hold(rx, backoff).await {
                        return;
                    }
                    backoff = (backoff * 2).min(self.reconnect_max);
                    continue;
                }
                Err(_) => {
                    self.failed(&mut failures, &"connection timed out", backoff);
                    if !self.hold(rx, backoff).await {
                        return;
                    }
                    backoff = (backoff * 2).min(self.reconnect_max);
                    continue;
                }
            };
            self.stats.connects.fetch_add(1, Ordering::Relaxed);
            tracing::info!(endpoint = %self.endpoint, "CoT: connected");
            failures = 0;
            backoff = FIRST_BACKOFF;
            match self.stream_until_lost(rx, stream).await {
                Some(e) => {
                    self.stats.errors.fetch_add(1, Ordering::Relaxed);
                    tracing::warn!(endpoint = %self.endpoint, error = %e, "CoT: connection lost; reconnecting");
                    // Some servers drop a client whose uid reconnects at once.
                    if !self.hold(rx, FIRST_BACKOFF).await {
                        return;
                    }
                }
                None => return,
            }
        }
    }

    fn failed(&self, failures: &mut u64, e: &dyn std::fmt::Display, backoff: Duration) {
        self.stats.errors.fetch_add(1, Ordering::Relaxed);
        *failures += 1;
        if failures.is_power_of_two() {
            tracing::warn!(
                endpoint = %self.endpoint,
                error = %e,
                attempts = *failures,
                retry_s = backoff.as_secs_f64(),
                "CoT: cannot reach the server"
            );
        }
    }

    /// Sends the identity, what was kept while away, then every event as it comes. Returns
    /// why the connection was lost, or `None` when the output closed.
    async fn stream_until_lost(
        &mut self,
        rx: &mut mpsc::Receiver<CotMessage>,
        stream: Box<dyn Stream>,
    ) -> Option<String> {
        let (mut reader, mut writer) = tokio::io::split(stream);
        let identity = (self.identity)();
        if let Err(e) = write(&mut writer, &identity).await {
            return Some(e);
        }
        for m in self.pending.take() {
            if let Err(e) = write(&mut writer, &m).await {
                if self.pending.put(m) {
                    self.stats.replaced.fetch_add(1, Ordering::Relaxed);
                }
                return Some(e);
            }
            self.stats.sent.fetch_add(1, Ordering::Relaxed);
        }
        // The server may send (pings, other clients' events): read and drop, and see it close.
        let mut sink = vec![0u8; 16 * 1024];
        loop {
            tokio::select! {
                m = rx.recv() => {
                    let Some(m) = m else {
                        close_cleanly(&mut reader, &mut writer).await;
                        return None;
                    };
                    if let Err(e) = write(&mut writer, &m).await {
                        if self.pending.put(m) {
                            self.stats.replaced.fetch_add(1, Ordering::Relaxed);
                        }
                        return Some(e);
                    }
                    self.stats.sent.fetch_add(1, Ordering::Relaxed);
                }
                n = reader.read(&mut sink) => match n {
                    Ok(0) => return Some("the server closed the connection".into()),
                    Ok(_) => {}
                    Err(e) => return Some(e.to_string()),
                },
            }
        }
    }
}

/// Ends a stream: our side's end of data after everything written (FIN), then what the server
/// still sends is read until it closes too (or 2 s pass), so nothing is left unread and the
/// close is not a reset.
async fn close_cleanly(
    reader: &mut (impl AsyncRead + Unpin),
    writer: &mut (impl AsyncWrite + Unpin),
) {
    let _ = tokio::time::timeout(IO_TIMEOUT, writer.shutdown()).await;
    let mut sink = vec![0u8; 16 * 1024];
    let _ = tokio::time::timeout(Duration::from_secs(2), async {
        while let Ok(n) = reader.read(&mut sink).await {
            if n == 0 {
                break;
            }
        }
    })
    .await;
}

async fn write(w: &mut (impl AsyncWrite + Unpin), m: &CotMessage) -> Result<(), String> {
    match tokio::time::timeout(IO_TIMEOUT, async {
        w.write_all(m.xml.as_bytes()).await?;
        w.flush().await
    })
    .await
    {
        Ok(Ok(())) => Ok(()),
        Ok(Err(e)) => Err(e.to_string()),
        Err(_) => Err(format!(
            "a write took longer than {} s",
            IO_TIMEOUT.as_secs()
        )),
    }
}

async fn connect(endpoint: &CotEndpoint) -> Result<Box<dyn Stream>, String> {
    match endpoint {
        CotEndpoint::Tcp { host, port } => {
            let s = TcpStream::connect((host.as_str(), *port))
                .await
                .map_err(|e| e.to_string())?;
            let _ = s.set_nodelay(true);
            Ok(Box::new(s))
        }
        CotEndpoint::Tls { host, port, files } => {
            let connector = tls::connector(files).map_err(|e| e.to_string())?;
            let s = TcpStream::connect((host.as_str(), *port))
                .await
                .map_err(|e| e.to_string())?;
            let _ = s.set_nodelay(true);
            let name = tls::server_name(host).map_err(|e| e.to_string())?;
            let s = connector
                .connect(name, s)
                .await
                .map_err(|e| format!("TLS handshake: {e}"))?;
            Ok(Box::new(s))
        }
        CotEndpoint::Udp { .. } => Err("not a stream endpoint".into()),
    }
}

/// A UDP socket for `host:port`, set up for multicast when the address is a group.
async fn open_udp(
    host: &str,
    port: u16,
    interface: Option<Ipv4Addr>,
    ttl: u32,
) -> std::io::Result<(UdpSocket, SocketAddr)> {
    let to = tokio::net::lookup_host((host, port))
        .await?
        .next()
        .ok_or_else(|| std::io::Error::other(format!("{host} has no address")))?;
    let bind: SocketAddr = if to.is_ipv4() {
        (Ipv4Addr::UNSPECIFIED, 0).into()
    } else {
        (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
    };
    let socket = UdpSocket::bind(bind).await?;
    if let SocketAddr::V4(v4) = to {
        if v4.ip().is_multicast() {
            socket.set_multicast_ttl_v4(ttl)?;
            socket.set_multicast_loop_v4(true)?;
            if let Some(iface) = interface {
                set_multicast_interface_v4(&socket, iface)?;
            }
        }
    }
    Ok((socket, to))
}

/// IP_MULTICAST_IF: the interface (by address) multicast leaves from.
fn set_multicast_interface_v4(socket: &UdpSocket, iface: Ipv4Addr) -> std::io::Result<()> {
    socket2::SockRef::from(socket).set_multicast_if_v4(&iface)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn m(uid: &str, n: u32) -> CotMessage {
        CotMessage {
            uid: uid.into(),
            xml: format!("<event n=\"{n}\"/>").into(),
        }
    }

    #[test]
    fn pending_keeps_the_latest_event_of_each_uid_in_first_seen_order() {
        let mut p = Pending::default();
        assert!(!p.put(m("a", 1)));
        assert!(!p.put(m("b", 2)));
        assert!(p.put(m("a", 3)));
        let xml: Vec<String> = p.take().iter().map(|m| m.xml.to_string()).collect();
        assert_eq!(xml, vec!["<event n=\"3\"/>", "<event n=\"2\"/>"]);
        assert!(p.take().is_empty());
    }
}
