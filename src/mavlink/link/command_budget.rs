//! How many commands each sender may have answered: a token bucket per (system, component).
//!
//! Every COMMAND_LONG / COMMAND_INT addressed to mgmot is owed a COMMAND_ACK, and most are
//! logged. A flood of commands (a runaway script, a stuck ground station, an attack on the
//! link) would have mgmot answer and log as fast as it can read. Commands beyond a sender's
//! budget are dropped unanswered and counted: the command protocol retries an unanswered
//! command, so a real operator's click still goes through, a moment later.

use std::collections::HashMap;
use std::time::Instant;

/// Commands a sender may send per second, sustained.
pub const COMMANDS_PER_S: f64 = 10.0;

/// Commands a sender may send in a burst (a ground station's retries, a few clicks).
pub const COMMAND_BURST: f64 = 20.0;

/// Senders remembered: beyond this, the one heard from least recently is forgotten (a flood
/// from many forged ids cannot grow the table).
pub const MAX_SENDERS: usize = 64;

#[derive(Debug, Clone, Copy)]
struct Bucket {
    tokens: f64,
    at: Instant,
}

/// The per-sender budget.
#[derive(Debug, Default)]
pub struct CommandBudget {
    senders: HashMap<(u8, u8), Bucket>,
}

impl CommandBudget {
    /// Whether a command from `sender` (system, component) arriving at `now` is within its
    /// budget (and takes one token if so).
    pub fn admit(&mut self, sender: (u8, u8), now: Instant) -> bool {
        if !self.senders.contains_key(&sender) && self.senders.len() >= MAX_SENDERS {
            if let Some(oldest) = self
                .senders
                .iter()
                .min_by_key(|(_, b)| b.at)
                .map(|(k, _)| *k)
            {
                self.senders.remove(&oldest);
            }
        }
        let b = self.senders.entry(sender).or_insert(Bucket {
            tokens: COMMAND_BURST,
            at: now,
        });
        let refill = now.saturating_duration_since(b.at).as_secs_f64() * COMMANDS_PER_S;
        b.tokens = (b.tokens + refill).min(COMMAND_BURST);
        b.at = now;
        if b.tokens >= 1.0 {
            b.tokens -= 1.0;
            true
        } else {
            false
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    /// A flood at 5,000 commands a second for 30 s is answered at the sustained rate (plus the
    /// burst), and another sender is not starved by it.
    #[test]
    fn a_flood_is_held_to_the_budget_and_others_still_get_through() {
        let mut b = CommandBudget::default();
        let t0 = Instant::now();
        let mut admitted = 0u64;
        let mut operator = 0u64;
        for k in 0..150_000u64 {
            let now = t0 + Duration::from_micros(k * 200);
            admitted += u64::from(b.admit((255, 190), now));
            if k % 5_000 == 0 {
                operator += u64::from(b.admit((255, 1), now));
            }
        }
        let expected = 30.0 * COMMANDS_PER_S + COMMAND_BURST;
        assert!(
            (admitted as f64 - expected).abs() <= 2.0,
            "{admitted} admitted, {expected} expected"
        );
        assert_eq!(operator, 30);
    }

    #[test]
    fn forged_senders_cannot_grow_the_table() {
        let mut b = CommandBudget::default();
        let now = Instant::now();
        for s in 0..=255u8 {
            for c in 0..=255u8 {
                b.admit((s, c), now);
            }
        }
        assert_eq!(b.senders.len(), MAX_SENDERS);
    }
}
