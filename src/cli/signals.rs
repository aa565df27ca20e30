//! The long-running subcommands' async runtime: two worker threads and a shutdown that
//! SIGINT or SIGTERM fires.

use anyhow::Context;
use mgmot::pipeline::{shutdown_signal, Shutdown};
use std::future::Future;

/// Runs `body` to its end on a two-worker tokio runtime; SIGINT or SIGTERM fires the
/// [`Shutdown`] it is given (each logged), so it can stop cleanly.
pub fn run_until_signal<T, F, Fut>(body: F) -> anyhow::Result<T>
where
    F: FnOnce(Shutdown) -> Fut,
    Fut: Future<Output = anyhow::Result<T>>,
{
    let runtime = tokio::runtime::Builder::new_multi_thread()
        .worker_threads(2)
        .enable_all()
        .build()
        .context("starting the async runtime")?;
    runtime.block_on(async move {
        let (trigger, shutdown) = shutdown_signal();
        let mut sigterm = tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate())
            .context("installing the SIGTERM handler")?;
        let signals = tokio::spawn(async move {
            tokio::select! {
                _ = tokio::signal::ctrl_c() => tracing::info!("SIGINT: stopping"),
                _ = sigterm.recv() => tracing::info!("SIGTERM: stopping"),
            }
            trigger.fire();
        });
        let out = body(shutdown).await;
        signals.abort();
        out
    })
}
