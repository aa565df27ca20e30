//! The pipeline's side of the send queue: [`LinkSender`].

use crate::mavlink::dialect::MavMessage;
use crate::telemetry::CompanionTimeUs;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use tokio::sync::mpsc;

/// Called with the time a message went out on the socket.
pub type OnSent = Box<dyn FnOnce(CompanionTimeUs) + Send>;

pub(super) struct Outgoing {
    pub(super) message: MavMessage,
    pub(super) on_sent: Option<OnSent>,
}

/// Queues messages for the link (cheap to clone). When the queue is full, messages are
/// dropped and counted rather than blocking.
#[derive(Clone)]
pub struct LinkSender {
    tx: mpsc::Sender<Outgoing>,
    dropped: Arc<AtomicU64>,
}

impl std::fmt::Debug for LinkSender {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LinkSender")
            .field("dropped", &self.dropped())
            .finish_non_exhaustive()
    }
}

impl LinkSender {
    /// A sender on the link's queue.
    pub(super) fn new(tx: mpsc::Sender<Outgoing>) -> Self {
        Self {
            tx,
            dropped: Arc::new(AtomicU64::new(0)),
        }
    }

    /// Queues `message`.
    pub fn send(&self, message: MavMessage) {
        self.queue(Outgoing {
            message,
            on_sent: None,
        });
    }

    /// Queues `message`; `on_sent` is called with the time it was written to the socket.
    pub fn send_then(&self, message: MavMessage, on_sent: OnSent) {
        self.queue(Outgoing {
            message,
            on_sent: Some(on_sent),
        });
    }

    fn queue(&self, out: Outgoing) {
        if self.tx.try_send(out).is_err() {
            self.dropped.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// Messages dropped because the queue was full.
    pub fn dropped(&self) -> u64 {
        self.dropped.load(Ordering::Relaxed)
    }
}
