//! The heartbeat and the telemetry watch: HEARTBEAT at its configured rate, and twice a second
//! whether position telemetry still flows and whether any was refused as implausible,
//! announced on change only (the core's [`ConditionReport`], the same reporter the camera and
//! the detector use).

use super::shutdown::Shutdown;
use super::telemetry::TelemetryState;
use crate::health::{Condition, ConditionReport, Level, Notice};
use crate::mavlink::Outputs;
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How often telemetry's arrival is checked.
const CHECK_EVERY: Duration = Duration::from_millis(500);

/// Sends a notice to the operator and the log.
pub(super) fn announce(outputs: &Outputs, notice: &Notice) {
    match notice.level {
        Level::Info | Level::Notice => tracing::info!("{}", notice.text),
        Level::Warning => tracing::warn!("{}", notice.text),
    }
    outputs.notice(notice);
}

/// Runs until `shutdown` fires. Telemetry is "lost" when no position has arrived for
/// `lost_after`; before the first fix it has had since start-up to arrive.
pub(super) async fn heartbeat_and_telemetry_watch(
    outputs: Outputs,
    telemetry: Arc<Mutex<TelemetryState>>,
    mut shutdown: Shutdown,
    heartbeat_every: Duration,
    lost_after: Duration,
) {
    let mut heartbeat = tokio::time::interval(heartbeat_every);
    heartbeat.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut check = tokio::time::interval(CHECK_EVERY);
    let mut report = ConditionReport::new(Condition::Telemetry);
    let mut plausible = ConditionReport::new(Condition::Plausibility);
    // The companion clock is CLOCK_MONOTONIC (time since boot): start-up is now, not 0.
    let started = crate::clock::now();
    let lost_after_us = u64::try_from(lost_after.as_micros()).unwrap_or(u64::MAX);
    loop {
        tokio::select! {
            _ = shutdown.recv() => break,
            _ = heartbeat.tick() => {
                outputs.heartbeat();
                continue;
            }
            _ = check.tick() => {}
        }
        let now = crate::clock::now();
        let Ok((last_position_at, (sane, why))) = telemetry
            .lock()
            .map(|t| (t.last_position_at(), t.plausibility(now)))
        else {
            break;
        };
        let at = last_position_at.unwrap_or(started);
        let ok = now.0.saturating_sub(at.0) <= lost_after_us;
        if let Some(notice) = report.observe(ok, None) {
            announce(&outputs, &notice);
        }
        // Implausible telemetry: told once when the first sample is refused, and once when
        // nothing was refused for a while again.
        let why = why.map(|w| w.to_string());
        if let Some(notice) = plausible.observe(sane, why.as_deref()) {
            announce(&outputs, &notice);
        }
    }
}
