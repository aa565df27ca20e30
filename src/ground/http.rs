//! The local web server of the live map: `/` the page (self-contained: no internet needed),
//! `/tracks.geojson` the latest picture. One thread, tiny_http; GET and HEAD only.

use std::net::SocketAddr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, RwLock};
use std::thread::JoinHandle;
use std::time::Duration;

/// The map page.
pub const MAP_HTML: &str = include_str!("map.html");

/// Why the server did not start.
#[derive(Debug, thiserror::Error)]
#[error("cannot serve the map on http://{addr}/: {reason}")]
pub struct HttpError {
    /// The address asked for.
    pub addr: SocketAddr,
    /// Why (address in use, no permission).
    pub reason: String,
}

/// The running server; stops when dropped or [`MapServer::stop`]ped.
#[derive(Debug)]
pub struct MapServer {
    /// Where it listens (the port the OS chose when 0 was asked for).
    pub addr: SocketAddr,
    picture: Arc<RwLock<Arc<str>>>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
}

impl MapServer {
    /// Listens on `addr` and serves `picture` (an empty collection until the first update).
    pub fn start(addr: SocketAddr) -> Result<Self, HttpError> {
        let server = tiny_http::Server::http(addr).map_err(|e| HttpError {
            addr,
            reason: e.to_string(),
        })?;
        let bound = server.server_addr().to_ip().unwrap_or(addr);
        let picture: Arc<RwLock<Arc<str>>> = Arc::new(RwLock::new(Arc::from(
            r#"{"type":"FeatureCollection","properties":{"source":"mgmot ground"},"features":[]}"#,
        )));
        let stop = Arc::new(AtomicBool::new(false));
        let thread = {
            let (picture, stop) = (picture.clone(), stop.clone());
            std::thread::Builder::new()
                .name("ground-http".into())
                .spawn(move || serve(&server, &picture, &stop))
                .map_err(|e| HttpError {
                    addr,
                    reason: e.to_string(),
                })?
        };
        Ok(Self {
            addr: bound,
            picture,
            stop,
            thread: Some(thread),
        })
    }

    /// Replaces the picture served.
    pub fn publish(&self, geojson: Arc<str>) {
        if let Ok(mut p) = self.picture.write() {
            *p = geojson;
        }
    }

    /// Stops serving.
    pub fn stop(mut self) {
        self.halt();
    }

    fn halt(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
    }
}

impl Drop for MapServer {
    fn drop(&mut self) {
        self.halt();
    }
}

fn header(name: &str, value: &str) -> Option<tiny_http::Header> {
    tiny_http::Header::from_bytes(name.as_bytes(), value.as_bytes()).ok()
}

fn serve(server: &tiny_http::Server, picture: &RwLock<Arc<str>>, stop: &AtomicBool) {
    while !stop.load(Ordering::Relaxed) {
        let request = match server.recv_timeout(Duration::from_millis(100)) {
            Ok(Some(r)) => r,
            Ok(None) => continue,
            Err(e) => {
                tracing::warn!(error = %e, "map server: cannot accept a request");
                continue;
            }
        };
        let method_ok = matches!(
            request.method(),
            tiny_http::Method::Get | tiny_http::Method::Head
        );
        let path = request.url().split('?').next().unwrap_or("").to_owned();
        let (status, body, kind): (u16, Arc<str>, &str) = match (method_ok, path.as_str()) {
            (false, _) => (
                405,
                Arc::from("only GET and HEAD\n"),
                "text/plain; charset=utf-8",
            ),
            (true, "/" | "/index.html") => (200, Arc::from(MAP_HTML), "text/html; charset=utf-8"),
            (true, "/tracks.geojson") => (
                200,
                picture
                    .read()
                    .map(|p| p.clone())
                    .unwrap_or_else(|p| p.into_inner().clone()),
                "application/geo+json",
            ),
            _ => (
                404,
                Arc::from("not found: / (the map) and /tracks.geojson\n"),
                "text/plain; charset=utf-8",
            ),
        };
        let mut response =
            tiny_http::Response::from_string(body.to_string()).with_status_code(status);
        for h in [
            header("Content-Type", kind),
            header("Cache-Control", "no-store"),
            header("X-Content-Type-Options", "nosniff"),
        ]
        .into_iter()
        .flatten()
        {
            response.add_header(h);
        }
        if let Err(e) = request.respond(response) {
            tracing::debug!(error = %e, "map server: the client went away");
        }
    }
}
