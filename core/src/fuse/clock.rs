//! One clock for every drone's reports.
//!
//! MGMOT_TRACK is stamped on its autopilot's boot clock, which differs per drone. The
//! autopilot's SYSTEM_TIME pairs that clock with UTC (from GNSS): the offset maps each
//! drone's stamps onto UTC. Where a drone's SYSTEM_TIME never arrives (or carries no UTC),
//! the stamps are mapped onto the ground's own clock by the smallest arrival delay seen (the
//! one-way estimate: the fastest message had the least queueing).
//!
//! The fuser's "now" is the ground's clock minus the smallest lag of the reports behind it
//! over the last [`LAG_WINDOW_S`]: with GNSS time on both sides that lag is the link's
//! latency; on a bench whose simulated UTC is another day it absorbs the difference.

use std::collections::{BTreeMap, VecDeque};

/// Seconds of reports over which the smallest lag is taken.
pub const LAG_WINDOW_S: f64 = 30.0;

/// A boot time moving back by more than this (s) is an autopilot reboot: its offset is
/// learnt anew.
const REBOOT_BACK_S: f64 = 1.0;

#[derive(Debug, Clone, Copy, Default)]
struct VehicleOffset {
    /// UTC minus boot time (s), from SYSTEM_TIME.
    utc: Option<f64>,
    /// Ground arrival minus boot time (s): the smallest seen.
    arrival: Option<f64>,
    /// The latest boot time seen (s), to notice a reboot.
    last_boot_s: f64,
}

/// Maps the drones' boot-clock stamps onto one clock and tells the fuser's time.
#[derive(Debug, Clone, Default)]
pub struct ClockAlign {
    vehicles: BTreeMap<u8, VehicleOffset>,
    /// (ground arrival, lag = arrival - aligned time), the last [`LAG_WINDOW_S`].
    lags: VecDeque<(f64, f64)>,
}

impl ClockAlign {
    /// Nothing known yet.
    pub fn new() -> Self {
        Self::default()
    }

    fn vehicle(&mut self, system_id: u8, boot_s: f64) -> &mut VehicleOffset {
        let v = self.vehicles.entry(system_id).or_default();
        if boot_s + REBOOT_BACK_S < v.last_boot_s {
            *v = VehicleOffset::default();
        }
        v.last_boot_s = v.last_boot_s.max(boot_s);
        v
    }

    /// A SYSTEM_TIME of `system_id`: UTC (s since the epoch; 0 = none) at boot time `boot_s`.
    pub fn system_time(&mut self, system_id: u8, utc_s: f64, boot_s: f64) {
        if !(utc_s > 0.0 && utc_s.is_finite() && boot_s.is_finite()) {
            return;
        }
        self.vehicle(system_id, boot_s).utc = Some(utc_s - boot_s);
    }

    /// The aligned time (s) of a stamp `boot_s` of `system_id` that arrived at the ground at
    /// `arrival_s` (the ground's clock). Records the lag for [`ClockAlign::now`].
    pub fn align(&mut self, system_id: u8, boot_s: f64, arrival_s: f64) -> f64 {
        let v = self.vehicle(system_id, boot_s);
        let seen = arrival_s - boot_s;
        v.arrival = Some(v.arrival.map_or(seen, |a: f64| a.min(seen)));
        let offset = v.utc.or(v.arrival).unwrap_or(seen);
        let aligned = boot_s + offset;
        self.lags.push_back((arrival_s, arrival_s - aligned));
        while self
            .lags
            .front()
            .is_some_and(|(t, _)| arrival_s - t > LAG_WINDOW_S)
        {
            self.lags.pop_front();
        }
        aligned
    }

    /// The fuser's time at ground time `ground_s`: the ground's clock less the smallest lag
    /// of the recent reports (`ground_s` itself before any report).
    pub fn now(&self, ground_s: f64) -> f64 {
        let lag = self
            .lags
            .iter()
            .map(|(_, l)| *l)
            .fold(f64::INFINITY, f64::min);
        if lag.is_finite() {
            ground_s - lag
        } else {
            ground_s
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn system_time_maps_two_boot_clocks_onto_utc() {
        let mut c = ClockAlign::new();
        // Drone 1 booted at UTC 1000 s, drone 2 at UTC 1050 s.
        c.system_time(1, 1100.0, 100.0);
        c.system_time(2, 1100.0, 50.0);
        assert_eq!(c.align(1, 120.0, 5000.2), 1120.0);
        assert_eq!(c.align(2, 70.0, 5000.3), 1120.0);
        // Now: the ground clock less the smallest lag (3880.2 s).
        assert!((c.now(5001.2) - 1121.0).abs() < 1e-9);
    }

    #[test]
    fn without_system_time_the_fastest_arrival_sets_the_offset() {
        let mut c = ClockAlign::new();
        let a = c.align(3, 10.0, 110.5);
        assert_eq!(a, 110.5);
        // A faster message lowers the offset; later stamps use it.
        c.align(3, 11.0, 111.1);
        assert!((c.align(3, 12.0, 113.0) - 112.1).abs() < 1e-9);
    }

    #[test]
    fn a_reboot_forgets_the_offset() {
        let mut c = ClockAlign::new();
        c.system_time(1, 2000.0, 500.0);
        assert_eq!(c.align(1, 501.0, 9000.0), 2001.0);
        // The boot clock restarts at 2 s: SYSTEM_TIME's old offset no longer holds.
        let a = c.align(1, 2.0, 9001.0);
        assert_eq!(a, 9001.0);
        c.system_time(1, 2010.0, 3.0);
        assert_eq!(c.align(1, 4.0, 9003.0), 2011.0);
    }

    #[test]
    fn a_missing_utc_is_ignored() {
        let mut c = ClockAlign::new();
        c.system_time(1, 0.0, 5.0);
        assert_eq!(c.align(1, 6.0, 100.0), 100.0);
        assert_eq!(c.now(42.0), 42.0 - 0.0);
    }
}
