//! Waiting in tests: on a condition, and for a test body that may hang.

use std::sync::mpsc;
use std::time::{Duration, Instant};

/// Polls `cond` every millisecond until it holds or `limit` passes; returns whether it held.
pub fn eventually(limit: Duration, mut cond: impl FnMut() -> bool) -> bool {
    let deadline = Instant::now() + limit;
    loop {
        if cond() {
            return true;
        }
        if Instant::now() >= deadline {
            return false;
        }
        std::thread::sleep(Duration::from_millis(1));
    }
}

/// Polls `f` every 50 ms until it is `Ok` or `limit` passes; then fails (panics) with `what`,
/// the time waited and the last thing `f` saw.
pub fn wait_until(what: &str, limit: Duration, mut f: impl FnMut() -> Result<(), String>) {
    let start = Instant::now();
    loop {
        let seen = match f() {
            Ok(()) => return,
            Err(seen) => seen,
        };
        if start.elapsed() > limit {
            panic!("timed out after {limit:?} waiting for {what}; last seen:\n{seen}");
        }
        std::thread::sleep(Duration::from_millis(50));
    }
}

/// Runs `f` on a thread of its own; fails (panics) if it does not end within `limit`, and
/// passes its panic on if it panics.
///
/// A hung thread is left behind (it cannot be stopped from outside): the test fails with its
/// name instead of hanging the whole run. `interrupted` is asked every 100 ms; when it says
/// so, the process exits with 130 (a module thread turns SIGINT into a flag the test process
/// must still obey).
pub fn watchdog(
    name: &str,
    limit: Duration,
    interrupted: fn() -> bool,
    f: impl FnOnce() + Send + 'static,
) {
    let (tx, rx) = mpsc::channel();
    std::thread::Builder::new()
        .name(name.to_owned())
        .spawn(move || {
            let r = std::panic::catch_unwind(std::panic::AssertUnwindSafe(f));
            let _ = tx.send(r);
        })
        .expect("spawn the test thread");
    let start = Instant::now();
    loop {
        match rx.recv_timeout(Duration::from_millis(100)) {
            Ok(Ok(())) => return,
            Ok(Err(panic)) => std::panic::resume_unwind(panic),
            Err(mpsc::RecvTimeoutError::Disconnected) => panic!("{name}: the test thread vanished"),
            Err(mpsc::RecvTimeoutError::Timeout) => {
                if interrupted() {
                    eprintln!("interrupted");
                    std::process::exit(130);
                }
                if start.elapsed() > limit {
                    panic!("{name} hangs: it did not finish within {limit:?}");
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn eventually_says_whether_the_condition_came_true() {
        let mut n = 0;
        assert!(eventually(Duration::from_secs(10), || {
            n += 1;
            n == 3
        }));
        assert!(!eventually(Duration::from_millis(5), || false));
    }

    #[test]
    #[should_panic(expected = "timed out after 1ms waiting for the moon; last seen:\n7")]
    fn wait_until_names_what_it_waited_for_and_what_it_saw() {
        wait_until("the moon", Duration::from_millis(1), || Err("7".into()));
    }

    #[test]
    #[should_panic(expected = "stuck hangs: it did not finish within 100ms")]
    fn a_watchdog_fails_a_body_that_hangs() {
        watchdog(
            "stuck",
            Duration::from_millis(100),
            || false,
            || std::thread::sleep(Duration::from_secs(3600)),
        );
    }

    #[test]
    #[should_panic(expected = "inner")]
    fn a_watchdog_passes_on_the_body_s_panic() {
        watchdog(
            "panics",
            Duration::from_secs(10),
            || false,
            || panic!("inner"),
        );
    }
}
