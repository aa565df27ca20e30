//! The link's transports: UDP (in and out), TCP (in and out) and serial, opened from a
//! connection string. Bytes in, bytes out; framing and policy live in the link.
//!
//! A stream transport (TCP, serial) has a reader task that forwards what it reads, so the
//! link's loop only ever waits on channels and sockets that are safe to cancel; the peer
//! closing or failing ends the reader and the link reconnects. UDP has no connection: errors
//! (an ICMP "port unreachable" from a `udpout` peer that is not up yet) are reported and the
//! socket kept.

use std::io;
use std::net::SocketAddr;
use tokio::io::{AsyncReadExt, AsyncWrite, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream, UdpSocket};
use tokio::sync::mpsc;
use tokio::task::JoinHandle;

/// Where the link connects, parsed from `serial:DEV:BAUD`, `udpin:HOST:PORT`,
/// `udpout:HOST:PORT`, `tcpin:HOST:PORT` or `tcpout:HOST:PORT`.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Endpoint {
    /// A serial port (a flight controller's TELEM port).
    Serial {
        /// Device path.
        device: String,
        /// Baud rate.
        baud: u32,
    },
    /// Listen for UDP on `HOST:PORT`; answer one peer (see the link).
    UdpIn(String),
    /// Send UDP to `HOST:PORT` and accept datagrams from it only.
    UdpOut(String),
    /// Listen for one TCP client at a time.
    TcpIn(String),
    /// Connect to a TCP server (reconnecting with back-off).
    TcpOut(String),
}

impl Endpoint {
    /// Parses a connection string checked by [`crate::mavlink::parse_connection`].
    pub fn parse(s: &str) -> Result<Self, super::super::address::AddressError> {
        super::super::address::parse_connection(s)?;
        let form = || super::super::address::AddressError::Form(s.to_owned());
        let (scheme, rest) = s.split_once(':').ok_or_else(form)?;
        Ok(match scheme {
            "serial" => {
                let (device, baud) = rest.rsplit_once(':').ok_or_else(form)?;
                Endpoint::Serial {
                    device: device.to_owned(),
                    baud: baud
                        .parse()
                        .map_err(|_| super::super::address::AddressError::Baud(s.to_owned()))?,
                }
            }
            "udpin" => Endpoint::UdpIn(rest.to_owned()),
            "udpout" => Endpoint::UdpOut(rest.to_owned()),
            "tcpin" => Endpoint::TcpIn(rest.to_owned()),
            "tcpout" => Endpoint::TcpOut(rest.to_owned()),
            _ => return Err(form()),
        })
    }

    /// Whether this is a UDP listener, whose peer is learnt from what arrives.
    pub fn is_udp_in(&self) -> bool {
        matches!(self, Endpoint::UdpIn(_))
    }
}

/// An open transport.
#[derive(Debug)]
pub enum Connection {
    /// A UDP socket; `remote` is the fixed peer of `udpout`.
    Udp {
        /// The socket.
        socket: UdpSocket,
        /// `udpout`'s peer.
        remote: Option<SocketAddr>,
    },
    /// TCP or serial.
    Stream(StreamConnection),
}

/// A TCP or serial connection: a reader task feeding `chunks`, and the write half.
pub struct StreamConnection {
    chunks: mpsc::Receiver<Vec<u8>>,
    writer: Box<dyn AsyncWrite + Send + Unpin>,
    reader: JoinHandle<()>,
    peer: String,
}

impl std::fmt::Debug for StreamConnection {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StreamConnection")
            .field("peer", &self.peer)
            .finish_non_exhaustive()
    }
}

impl Drop for StreamConnection {
    fn drop(&mut self) {
        self.reader.abort();
    }
}

/// What one receive gave.
#[derive(Debug)]
pub enum Received {
    /// Bytes (one datagram, or what a stream read), with the UDP sender.
    Bytes(Vec<u8>, Option<SocketAddr>),
    /// The stream ended (peer closed or failed): reconnect.
    Closed,
    /// A UDP error; the socket stays usable.
    Error(io::Error),
}

async fn resolve(host_port: &str) -> io::Result<SocketAddr> {
    tokio::net::lookup_host(host_port)
        .await?
        .next()
        .ok_or_else(|| io::Error::new(io::ErrorKind::NotFound, format!("{host_port}: no address")))
}

impl Connection {
    /// Opens `endpoint`. `tcpin` waits for a client; the others return at once or fail.
    pub async fn open(endpoint: &Endpoint) -> io::Result<Connection> {
        match endpoint {
            Endpoint::UdpIn(addr) => Ok(Connection::Udp {
                socket: UdpSocket::bind(resolve(addr).await?).await?,
                remote: None,
            }),
            Endpoint::UdpOut(addr) => {
                let remote = resolve(addr).await?;
                let any: SocketAddr = if remote.is_ipv4() {
                    ([0, 0, 0, 0], 0).into()
                } else {
                    (std::net::Ipv6Addr::UNSPECIFIED, 0).into()
                };
                Ok(Connection::Udp {
                    socket: UdpSocket::bind(any).await?,
                    remote: Some(remote),
                })
            }
            Endpoint::TcpOut(addr) => {
                let stream = TcpStream::connect(resolve(addr).await?).await?;
                stream.set_nodelay(true)?;
                let peer = stream.peer_addr()?.to_string();
                Ok(Connection::Stream(StreamConnection::spawn(stream, peer)))
            }
            Endpoint::TcpIn(addr) => {
                let listener = TcpListener::bind(resolve(addr).await?).await?;
                let (stream, peer) = listener.accept().await?;
                stream.set_nodelay(true)?;
                Ok(Connection::Stream(StreamConnection::spawn(
                    stream,
                    peer.to_string(),
                )))
            }
            Endpoint::Serial { device, baud } => {
                use tokio_serial::SerialPortBuilderExt as _;
                let port = tokio_serial::new(device, *baud)
                    .data_bits(tokio_serial::DataBits::Eight)
                    .parity(tokio_serial::Parity::None)
                    .stop_bits(tokio_serial::StopBits::One)
                    .flow_control(tokio_serial::FlowControl::None)
                    .open_native_async()
                    .map_err(io::Error::from)?;
                Ok(Connection::Stream(StreamConnection::spawn(
                    port,
                    device.clone(),
                )))
            }
        }
    }

    /// Waits for what arrives next. Safe to cancel.
    pub async fn recv(&mut self, buf: &mut [u8]) -> Received {
        match self {
            Connection::Udp { socket, .. } => match socket.recv_from(buf).await {
                Ok((n, from)) => Received::Bytes(buf[..n].to_vec(), Some(from)),
                Err(e) => Received::Error(e),
            },
            Connection::Stream(s) => match s.chunks.recv().await {
                Some(chunk) => Received::Bytes(chunk, None),
                None => Received::Closed,
            },
        }
    }

    /// Sends `bytes`: on UDP to `to` (or `udpout`'s peer); on a stream to the peer. A UDP
    /// send with nobody to send to is dropped (`Ok(false)`).
    pub async fn send(&mut self, bytes: &[u8], to: Option<SocketAddr>) -> io::Result<bool> {
        match self {
            Connection::Udp { socket, remote } => match to.or(*remote) {
                Some(addr) => socket.send_to(bytes, addr).await.map(|_| true),
                None => Ok(false),
            },
            Connection::Stream(s) => s.writer.write_all(bytes).await.map(|()| true),
        }
    }

    /// The peer, for logs.
    pub fn describe(&self) -> String {
        match self {
            Connection::Udp { socket, remote } => match (socket.local_addr(), remote) {
                (_, Some(r)) => format!("udp to {r}"),
                (Ok(l), None) => format!("udp on {l}"),
                (Err(_), None) => "udp".into(),
            },
            Connection::Stream(s) => s.peer.clone(),
        }
    }

    /// `udpout`'s fixed peer.
    pub fn fixed_remote(&self) -> Option<SocketAddr> {
        match self {
            Connection::Udp { remote, .. } => *remote,
            Connection::Stream(_) => None,
        }
    }
}

impl StreamConnection {
    fn spawn<S>(stream: S, peer: String) -> Self
    where
        S: tokio::io::AsyncRead + AsyncWrite + Send + 'static,
    {
        let (mut read, write) = tokio::io::split(stream);
        let (tx, chunks) = mpsc::channel(64);
        let reader = tokio::spawn(async move {
            let mut buf = vec![0u8; 4096];
            loop {
                match read.read(&mut buf).await {
                    Ok(0) | Err(_) => break,
                    Ok(n) => {
                        if tx.send(buf[..n].to_vec()).await.is_err() {
                            break;
                        }
                    }
                }
            }
        });
        StreamConnection {
            chunks,
            writer: Box::new(write),
            reader,
            peer,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn endpoints_parse() {
        assert_eq!(
            Endpoint::parse("serial:/dev/ttyAMA0:921600").unwrap(),
            Endpoint::Serial {
                device: "/dev/ttyAMA0".into(),
                baud: 921_600
            }
        );
        assert_eq!(
            Endpoint::parse("udpin:0.0.0.0:14550").unwrap(),
            Endpoint::UdpIn("0.0.0.0:14550".into())
        );
        assert!(Endpoint::parse("udpbcast:1.2.3.4:5").is_err());
    }

    #[tokio::test]
    async fn a_stream_closing_is_reported() {
        let listener = TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let server = tokio::spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            s.write_all(b"abc").await.unwrap();
        });
        let mut c = Connection::open(&Endpoint::TcpOut(addr.to_string()))
            .await
            .unwrap();
        server.await.unwrap();
        let mut buf = [0u8; 64];
        let mut got = Vec::new();
        loop {
            match c.recv(&mut buf).await {
                Received::Bytes(b, _) => got.extend(b),
                Received::Closed => break,
                Received::Error(e) => panic!("{e}"),
            }
        }
        assert_eq!(got, b"abc");
    }
}
