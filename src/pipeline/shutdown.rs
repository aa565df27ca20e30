//! One shutdown signal for every stage (the mini-redis shape): the caller decides what "stop"
//! means (SIGINT/SIGTERM in `mgmot run`, a oneshot in tests) and every stage holds a
//! [`Shutdown`] it polls (threads) or awaits (tasks).

use tokio::sync::watch;

/// The sending side: [`Trigger::fire`] tells every stage to stop.
#[derive(Debug)]
pub struct Trigger {
    tx: watch::Sender<bool>,
}

/// A stage's view of the shutdown signal.
#[derive(Debug, Clone)]
pub struct Shutdown {
    rx: watch::Receiver<bool>,
}

/// A new signal, not fired.
pub fn shutdown_signal() -> (Trigger, Shutdown) {
    let (tx, rx) = watch::channel(false);
    (Trigger { tx }, Shutdown { rx })
}

impl Trigger {
    /// Tells every stage to stop (idempotent).
    pub fn fire(&self) {
        self.tx.send_replace(true);
    }
}

impl Shutdown {
    /// Whether stop was asked (for blocking threads that check between frames). A dropped
    /// trigger also counts as stop: nobody could ever ask any more.
    pub fn is_shutdown(&self) -> bool {
        *self.rx.borrow() || self.rx.has_changed().is_err()
    }

    /// Completes when stop is asked (for async tasks in `select!`).
    pub async fn recv(&mut self) {
        // An error means the trigger is gone, which also means stop.
        let _ = self.rx.wait_for(|stop| *stop).await;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fire_reaches_every_clone() {
        let (trigger, a) = shutdown_signal();
        let b = a.clone();
        assert!(!a.is_shutdown());
        trigger.fire();
        assert!(a.is_shutdown() && b.is_shutdown());
    }

    #[test]
    fn dropped_trigger_means_stop() {
        let (trigger, a) = shutdown_signal();
        drop(trigger);
        assert!(a.is_shutdown());
    }

    #[tokio::test]
    async fn recv_completes_on_fire() {
        let (trigger, mut a) = shutdown_signal();
        let waiter = tokio::spawn(async move { a.recv().await });
        trigger.fire();
        tokio::time::timeout(std::time::Duration::from_secs(5), waiter)
            .await
            .unwrap()
            .unwrap();
    }
}
