//! The newest-frame slot between capture and inference: capture never waits, inference always
//! gets the most recent frame, and every frame overwritten unseen is counted. A stale frame is
//! worth nothing to a tracker in the air. For bench runs whose source can wait (the simulator
//! in lockstep), [`SlotWriter::put_waiting`] holds capture until inference took the previous
//! frame, within a bound, so that every frame is processed on any machine.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

#[derive(Debug)]
struct State<T> {
    value: Option<T>,
    closed: bool,
}

#[derive(Debug)]
struct Inner<T> {
    state: Mutex<State<T>>,
    ready: Condvar,
    /// Signalled when the reader takes a value.
    taken: Condvar,
    /// Frames overwritten before inference took them.
    dropped: AtomicU64,
}

/// The writing end (capture thread).
#[derive(Debug)]
pub struct SlotWriter<T> {
    inner: Arc<Inner<T>>,
}

/// The reading end (inference thread).
#[derive(Debug)]
pub struct SlotReader<T> {
    inner: Arc<Inner<T>>,
}

/// What [`SlotReader::take`] found.
#[derive(Debug, PartialEq)]
pub enum Taken<T> {
    /// The newest value.
    Value(T),
    /// Nothing arrived within the timeout.
    Timeout,
    /// The writer is gone and the slot is empty: no more values will come.
    Closed,
}

/// A newest-value slot.
pub fn newest_slot<T>() -> (SlotWriter<T>, SlotReader<T>) {
    let inner = Arc::new(Inner {
        state: Mutex::new(State {
            value: None,
            closed: false,
        }),
        ready: Condvar::new(),
        taken: Condvar::new(),
        dropped: AtomicU64::new(0),
    });
    (
        SlotWriter {
            inner: inner.clone(),
        },
        SlotReader { inner },
    )
}

impl<T> SlotWriter<T> {
    /// Puts a value, replacing (and counting) one not yet taken. Returns `false` when the
    /// reader is gone.
    pub fn put(&self, value: T) -> bool {
        if Arc::strong_count(&self.inner) < 2 {
            return false;
        }
        // A poisoned lock only means another thread panicked mid-update of a plain Option;
        // the data is still a valid Option.
        let mut state = self.inner.state.lock().unwrap_or_else(|e| e.into_inner());
        if state.value.replace(value).is_some() {
            self.inner.dropped.fetch_add(1, Ordering::Relaxed);
        }
        drop(state);
        self.inner.ready.notify_one();
        true
    }

    /// Puts a value once the reader has taken the previous one, waiting at most `limit` for
    /// that; after it, replaces the old value (counted) as [`SlotWriter::put`] does, so a
    /// stalled reader never stops capture for longer. Returns `false` when the reader is gone.
    pub fn put_waiting(&self, value: T, limit: Duration) -> bool {
        if Arc::strong_count(&self.inner) < 2 {
            return false;
        }
        let state = self.inner.state.lock().unwrap_or_else(|e| e.into_inner());
        let (mut state, _) = self
            .inner
            .taken
            .wait_timeout_while(state, limit, |s| {
                s.value.is_some() && Arc::strong_count(&self.inner) >= 2
            })
            .unwrap_or_else(|e| e.into_inner());
        if Arc::strong_count(&self.inner) < 2 {
            return false;
        }
        if state.value.replace(value).is_some() {
            self.inner.dropped.fetch_add(1, Ordering::Relaxed);
        }
        drop(state);
        self.inner.ready.notify_one();
        true
    }

    /// Frames dropped so far.
    pub fn dropped(&self) -> u64 {
        self.inner.dropped.load(Ordering::Relaxed)
    }
}

impl<T> Drop for SlotWriter<T> {
    fn drop(&mut self) {
        let mut state = self.inner.state.lock().unwrap_or_else(|e| e.into_inner());
        state.closed = true;
        drop(state);
        self.inner.ready.notify_all();
    }
}

impl<T> SlotReader<T> {
    /// Waits up to `timeout` for a value and takes it.
    pub fn take(&self, timeout: Duration) -> Taken<T> {
        let state = self.inner.state.lock().unwrap_or_else(|e| e.into_inner());
        let (mut state, _) = self
            .inner
            .ready
            .wait_timeout_while(state, timeout, |s| s.value.is_none() && !s.closed)
            .unwrap_or_else(|e| e.into_inner());
        match state.value.take() {
            Some(v) => {
                drop(state);
                self.inner.taken.notify_all();
                Taken::Value(v)
            }
            None if state.closed => Taken::Closed,
            None => Taken::Timeout,
        }
    }

    /// Frames dropped so far.
    pub fn dropped(&self) -> u64 {
        self.inner.dropped.load(Ordering::Relaxed)
    }
}

impl<T> Drop for SlotReader<T> {
    fn drop(&mut self) {
        // A writer waiting in `put_waiting` sees the reader gone at once.
        let state = self.inner.state.lock().unwrap_or_else(|e| e.into_inner());
        drop(state);
        self.inner.taken.notify_all();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newest_wins_and_drops_are_counted() {
        let (w, r) = newest_slot();
        assert!(w.put(1));
        assert!(w.put(2));
        assert!(w.put(3));
        assert_eq!(r.take(Duration::ZERO), Taken::Value(3));
        assert_eq!(r.dropped(), 2);
        assert_eq!(r.take(Duration::from_millis(1)), Taken::Timeout);
        w.put(4);
        drop(w);
        // A value still in the slot is delivered before the close.
        assert_eq!(r.take(Duration::ZERO), Taken::Value(4));
        assert_eq!(r.take(Duration::from_secs(5)), Taken::Closed);
    }

    #[test]
    fn writer_learns_the_reader_is_gone() {
        let (w, r) = newest_slot::<u8>();
        drop(r);
        assert!(!w.put(1));
    }

    #[test]
    fn wakes_a_waiting_reader() {
        let (w, r) = newest_slot();
        let t = std::thread::spawn(move || r.take(Duration::from_secs(10)));
        std::thread::sleep(Duration::from_millis(20));
        w.put(7u32);
        assert_eq!(t.join().unwrap(), Taken::Value(7));
    }

    #[test]
    fn put_waiting_holds_until_taken_then_replaces_after_the_limit() {
        let (w, r) = newest_slot();
        assert!(w.put_waiting(1, Duration::from_millis(10)));
        let reader = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(50));
            let first = r.take(Duration::ZERO);
            let second = r.take(Duration::from_secs(5));
            (first, second, r)
        });
        // Waits for the reader to take 1, then puts 2: nothing dropped.
        assert!(w.put_waiting(2, Duration::from_secs(5)));
        let (first, second, r) = reader.join().unwrap();
        assert_eq!((first, second), (Taken::Value(1), Taken::Value(2)));
        assert_eq!(r.dropped(), 0);
        // A reader that does not take: the limit passes and the value is replaced, counted.
        assert!(w.put_waiting(3, Duration::ZERO));
        assert!(w.put_waiting(4, Duration::from_millis(20)));
        assert_eq!(r.take(Duration::ZERO), Taken::Value(4));
        assert_eq!(r.dropped(), 1);
        // The reader gone: at once.
        w.put(5);
        drop(r);
        assert!(!w.put_waiting(6, Duration::from_secs(60)));
    }
}
