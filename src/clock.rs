//! The companion computer's monotonic clock, read at the edges (capture, link, pipeline); the
//! pure core only receives its values ([`CompanionTimeUs`]).

use crate::telemetry::CompanionTimeUs;

/// Now on `CLOCK_MONOTONIC`, the clock V4L2 stamps its buffers with, so every companion time
/// in the runtime (frames, telemetry arrival, latency) is on it.
pub fn now() -> CompanionTimeUs {
    let mut ts = libc::timespec {
        tv_sec: 0,
        tv_nsec: 0,
    };
    // SAFETY: `ts` is a valid, writable timespec; CLOCK_MONOTONIC exists on every Linux, so
    // the call cannot fail (it would leave `ts` at zero if it did).
    unsafe { libc::clock_gettime(libc::CLOCK_MONOTONIC, &mut ts) };
    // time_t and c_long are 32-bit on some targets.
    #[allow(clippy::unnecessary_cast)]
    CompanionTimeUs::from_timespec(ts.tv_sec as i64, ts.tv_nsec as i64 / 1000)
}

/// Now on the system's UTC clock, in µs since the Unix epoch (0 if the clock is set before
/// it): the wall time that outputs for other systems (Cursor-on-Target) carry. A companion
/// computer keeps it with NTP or the autopilot's GPS time.
pub fn unix_now_us() -> i64 {
    std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0, |d| i64::try_from(d.as_micros()).unwrap_or(i64::MAX))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_monotonic_clock_goes_forward() {
        let a = super::now();
        std::thread::sleep(std::time::Duration::from_millis(2));
        let b = super::now();
        assert!(b.0 >= a.0 + 2_000, "{a:?} -> {b:?}");
    }
}
