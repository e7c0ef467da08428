//! The one real-time thread of a process: a grid process puts the thread that keeps time or
//! serves releases under SCHED_FIFO itself (the supervisor sets whole processes: `rt`).

/// Runs the calling thread under SCHED_FIFO at `priority` (none: leaves it alone), with
/// reset-on-fork: every thread it starts afterwards (a loader, a port opener) runs at normal
/// priority. A grid process calls it on the one thread that keeps time or serves releases;
/// a refusal is a warning, naming `what`, and the thread runs with normal scheduling.
pub fn real_time_thread(priority: Option<u8>, what: &str) {
    let Some(priority) = priority else {
        return;
    };
    let param = libc::sched_param {
        sched_priority: i32::from(priority),
    };
    let policy = libc::SCHED_FIFO | libc::SCHED_RESET_ON_FORK;
    // SAFETY: `param` is a valid sched_param that outlives the call; pid 0 is this thread.
    if unsafe { libc::sched_setscheduler(0, policy, &param) } != 0 {
        tracing::warn!(
            "{what}: SCHED_FIFO priority {priority} not applied ({}); normal scheduling",
            std::io::Error::last_os_error()
        );
    }
}

/// Whether the calling thread runs under SCHED_FIFO.
pub fn runs_fifo() -> bool {
    // SAFETY: sched_getscheduler only reads the scheduling policy of thread 0 (this one).
    let policy = unsafe { libc::sched_getscheduler(0) };
    policy >= 0 && policy & !libc::SCHED_RESET_ON_FORK == libc::SCHED_FIFO
}
