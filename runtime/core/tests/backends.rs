//! The module runtime, exercised through both transport backends.
//!
//! Every scenario below is a function generic over [`support::Backend`]; [`on_both_backends!`]
//! instantiates it as `local::<name>` (in-process crossbeam channels) and `ipc::<name>`
//! (iceoryx2 shared memory), so `cargo test -p modbot-runtime --test backends` runs each one
//! twice. Each test runs in a domain of its own under a watchdog, with its modules on threads
//! of their own, and ends by checking that the domain is empty (no module listed; for shared
//! memory, no file left in `/dev/shm` or `/tmp/iceoryx2`).
//!
//! Killing real processes is covered by the multi-process tests at the workspace root; here a
//! "dead" module is one killed in place (local backend), dropped by its thread (iceoryx2), or
//! crashed by unwinding its thread.

mod support;

use std::collections::{BTreeSet, HashMap};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use modbot_core::blackboard::Blackboard;
use modbot_core::calls::RetryPolicy;
use modbot_core::transport::{Dest, Joins, ReceiveMode, Transport, TransportError};
use modbot_core::{
    CallError, CallOptions, Ctx, MethodError, Module, ModuleBuilder, ModuleError, Reply, Report,
    Stats,
};
use modbot_ipc_schema::{
    Addr, Args, F64s, Frame, FrameKind, FrameSpec, NakCode, OwnedValue, Seq, SnapshotView, Value,
};
use support::{crash, eventually, pump, stopping, Backend, Heard, TestDomain, PATIENCE};

/// Instantiates every listed scenario for both backends. A scenario can carry attributes for
/// one backend only: `#[local(ignore = "...")]`, `#[ipc(ignore = "...")]` (in that order).
macro_rules! on_both_backends {
    ($( $(#[local($($l:tt)*)])? $(#[ipc($($i:tt)*)])? $name:ident, )*) => {
        mod local {
            $(
                $(#[$($l)*])?
                #[test]
                fn $name() {
                    crate::support::run_test::<crate::support::Local>(
                        stringify!($name),
                        super::$name::<crate::support::Local>,
                    );
                }
            )*
        }
        mod ipc {
            $(
                $(#[$($i)*])?
                #[test]
                fn $name() {
                    crate::support::run_test::<crate::support::Ipc>(
                        stringify!($name),
                        super::$name::<crate::support::Ipc>,
                    );
                }
            )*
        }
    };
}

on_both_backends! {
    a_call_gets_the_reply_of_the_method,
    a_method_without_results_answers_with_an_ack,
    an_unknown_method_fails_naming_the_module_the_method_and_the_known_ones,
    bad_arguments_are_refused_with_a_nak_naming_the_argument,
    a_busy_method_answers_with_a_nak_busy,
    an_unknown_module_name_fails_with_unknown_module,
    twenty_calls_outstanding_at_once_are_each_matched_to_their_answer,
    a_call_to_a_module_that_does_not_answer_times_out,
    a_full_inbox_refuses_frames_and_the_sender_learns_it,
    a_duplicate_name_or_address_is_refused_while_the_first_module_lives,
    a_module_started_later_is_found_by_name,
    a_killed_module_is_not_available,
    a_module_restarted_at_the_address_of_a_killed_one_keeps_serving,
    a_call_waiting_on_a_module_that_crashes_fails_without_waiting_for_its_timeout,
    a_call_to_a_module_that_is_down_fails_at_once,
    a_call_that_waits_for_its_peer_succeeds_once_the_peer_is_back,
    a_call_that_waits_for_a_peer_that_just_died_succeeds_once_the_peer_is_back,
    a_broadcast_reaches_every_other_module,
    a_module_does_not_hear_its_own_broadcast,
    a_multicast_reaches_exactly_the_members_of_its_group,
    snapshots_read_in_place_are_never_torn,
    blackboard_items_are_read_and_written_by_message,
    a_refused_device_write_leaves_the_item_unchanged,
    bb_set_refusals_carry_the_read_only_and_unknown_item_codes,
    malformed_frames_are_counted_as_rejected_and_the_module_keeps_serving,
    stats_count_frames_and_calls_and_record_the_latency_of_each_answered_call,
    an_operator_can_deactivate_a_module_and_activate_it_again,
    a_method_named_like_a_system_method_is_refused_at_open,
    a_busy_poll_module_answers_and_is_listed_with_its_mode,
    the_last_module_to_leave_removes_the_domains_files,
}

// ---------------------------------------------------------------------------------------------
// Modules the scenarios use.

/// A calculator. `tag` is added to every square, to tell two calculators apart; with `held`,
/// the test sees each `stall` begin and ends it.
#[derive(Debug, Default)]
struct Calc {
    tag: i64,
    held: Option<Held>,
}

impl Calc {
    fn tagged(tag: i64) -> Calc {
        Calc { tag, held: None }
    }

    /// A calculator whose stalls the test holds: returns it, where each stall says it began,
    /// and what ends a stall.
    fn held() -> (Calc, mpsc::Receiver<()>, mpsc::Sender<()>) {
        let (began, began_rx) = mpsc::channel();
        let (release_tx, release) = mpsc::channel();
        let held = Held { began, release };
        let calc = Calc {
            tag: 0,
            held: Some(held),
        };
        (calc, began_rx, release_tx)
    }
}

/// The test's hold on a calculator's `stall`: told when one begins, and ends it when told, so
/// a test neither guesses when the module is stalled nor how long the stall must last.
#[derive(Debug)]
struct Held {
    began: mpsc::Sender<()>,
    release: mpsc::Receiver<()>,
}

/// The calculator's method table.
fn calc(b: ModuleBuilder<Calc>) -> ModuleBuilder<Calc> {
    b.method("mix", mix)
        .method("nothing", nothing)
        .method("busy", busy)
        .method("square", square)
        .method("stall", stall)
        .method("crash", crash_now)
}

const CALC_METHODS: &str = "mix, nothing, busy, square, stall, crash";

/// `mix(f64, i64, bool, text, bytes, f64s)` → each transformed: doubled, incremented, negated,
/// upper-cased, reversed, each plus one.
fn mix(_: &mut Calc, _: &mut Ctx, a: &Args<'_>, r: &mut Reply) -> Result<(), MethodError> {
    let (f, i, b, t, bytes, xs) = (
        a.f64(0)?,
        a.i64(1)?,
        a.bool(2)?,
        a.text(3)?,
        a.bytes(4)?,
        a.f64s(5)?,
    );
    r.f64(f * 2.0);
    r.push(Value::I64(i + 1));
    r.push(Value::Bool(!b));
    r.push(Value::Text(&t.to_uppercase()));
    let reversed: Vec<u8> = bytes.iter().rev().copied().collect();
    r.push(Value::Bytes(&reversed));
    let plus_one: Vec<f64> = xs.iter().map(|x| x + 1.0).collect();
    r.push(Value::F64s(F64s::from_slice(&plus_one)));
    Ok(())
}

fn nothing(_: &mut Calc, _: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    Ok(())
}

fn busy(_: &mut Calc, _: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    Err(MethodError::Busy("the arm is moving".into()))
}

/// `square(i64)` → `x² + tag`.
fn square(s: &mut Calc, _: &mut Ctx, a: &Args<'_>, r: &mut Reply) -> Result<(), MethodError> {
    let x = a.i64(0)?;
    r.push(Value::I64(x * x + s.tag));
    Ok(())
}

/// `stall(ms)`: holds the module's thread (it serves nothing meanwhile) for `ms`, or, for a
/// held calculator, until the test ends the stall; then answers.
fn stall(s: &mut Calc, _: &mut Ctx, a: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    let until = Instant::now() + Duration::from_millis(a.i64(0)? as u64);
    if let Some(held) = &s.held {
        let _ = held.began.send(());
    }
    while Instant::now() < until && !stopping() {
        if let Some(held) = &s.held {
            if held.release.try_recv().is_ok() {
                break;
            }
        }
        std::thread::sleep(Duration::from_millis(1));
    }
    Ok(())
}

/// A stall that lasts until the test ends it (a minute at most, should the test fail first).
const HELD: i64 = 60_000;

/// `crash()`: the module dies without answering.
fn crash_now(_: &mut Calc, _: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    crash()
}

/// A module that records the REPORTs it hears.
struct Ear {
    heard: mpsc::Sender<Heard>,
}

fn ear(b: ModuleBuilder<Ear>) -> ModuleBuilder<Ear> {
    b.on_report(on_report).method("shout", shout)
}

fn on_report(s: &mut Ear, ctx: &mut Ctx, r: &Report<'_>) {
    let _ = s.heard.send(Heard::new(ctx.name(), r));
}

const SHOUT_TOPIC: u8 = 9;

/// `shout()`: broadcasts a REPORT.
fn shout(_: &mut Ear, ctx: &mut Ctx, _: &Args<'_>, _: &mut Reply) -> Result<(), MethodError> {
    let me = ctx.name().to_owned();
    ctx.report(Dest::Broadcast, SHOUT_TOPIC, &[Value::Text(&me)])
        .map_err(|e| MethodError::Failed(e.to_string()))
}

/// A module with a blackboard: `a` and `b` always written together, a writable `gain`, a
/// logical device `temp` sampled on read, and a device `limit` that refuses values above 1.
#[derive(Debug, Default)]
struct Store {
    n: i64,
}

fn store(b: ModuleBuilder<Store>) -> ModuleBuilder<Store> {
    let bb = Blackboard::builder()
        .item("a", OwnedValue::I64(0))
        .item("b", OwnedValue::I64(0))
        .writable_item("gain", OwnedValue::F64(1.0))
        .device(
            "temp",
            OwnedValue::F64(20.0),
            false,
            Some(Box::new(|v| {
                if let OwnedValue::F64(x) = v {
                    *x += 1.0;
                }
            })),
            None,
        )
        .device(
            "limit",
            OwnedValue::F64(0.5),
            true,
            None,
            Some(Box::new(|v| match v {
                OwnedValue::F64(x) if *x > 1.0 => {
                    Err(format!("{x} is above the maximum of 1").into())
                }
                _ => Ok(()),
            })),
        )
        .build()
        .expect("a valid blackboard");
    b.blackboard(bb)
        .snapshot_period(Duration::from_millis(20))
        .every(Duration::from_millis(2), step)
}

/// Writes `a` and `b` together: a snapshot that shows them different is torn.
fn step(s: &mut Store, ctx: &mut Ctx) {
    s.n += 1;
    ctx.bb.write("a", Value::I64(s.n)).expect("a is an i64");
    ctx.bb.write("b", Value::I64(s.n)).expect("b is an i64");
}

/// The timeout of the tests' calls: generous, since a call ends as soon as it is answered.
const CALL_TIMEOUT: Duration = Duration::from_secs(30);

fn opts() -> CallOptions {
    CallOptions::timeout(CALL_TIMEOUT)
}

/// Asserts that a call that failed after `waited` failed at once: well before its timeout
/// ([`CALL_TIMEOUT`]), which it would have reached had it waited for an answer.
fn assert_failed_at_once(waited: Duration) {
    assert!(
        waited < CALL_TIMEOUT / 2,
        "failed only after {waited:?}, near its {CALL_TIMEOUT:?} timeout"
    );
}

fn i64s(v: &[i64]) -> Vec<OwnedValue> {
    v.iter().map(|x| OwnedValue::I64(*x)).collect()
}

// ---------------------------------------------------------------------------------------------
// Calls.

/// Every value kind goes to a method and its results come back, small and large.
fn a_call_gets_the_reply_of_the_method<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    let sut = caller.call_owned(
        "calc",
        "mix",
        &[
            Value::F64(1.5),
            Value::I64(41),
            Value::Bool(true),
            Value::Text("héllo"),
            Value::Bytes(&[1, 2, 3]),
            Value::F64s(F64s::from_slice(&[0.5, -1.0])),
        ],
        opts(),
    );
    assert_eq!(
        sut,
        Ok(vec![
            OwnedValue::F64(3.0),
            OwnedValue::I64(42),
            OwnedValue::Bool(false),
            OwnedValue::Text("HÉLLO".into()),
            OwnedValue::Bytes(vec![3, 2, 1]),
            OwnedValue::F64s(vec![1.5, 0.0]),
        ])
    );

    // 32 KiB of arguments: the extended frame form.
    let big: Vec<f64> = (0..4000).map(f64::from).collect();
    let sut = caller
        .call_owned(
            "calc",
            "mix",
            &[
                Value::F64(0.0),
                Value::I64(0),
                Value::Bool(false),
                Value::Text(""),
                Value::Bytes(&[]),
                Value::F64s(F64s::from_slice(&big)),
            ],
            opts(),
        )
        .expect("a large call is answered");
    let expected: Vec<f64> = big.iter().map(|x| x + 1.0).collect();
    assert_eq!(sut[5], OwnedValue::F64s(expected));
}

/// A method that pushes no result answers with an ACK: the caller gets an empty list.
fn a_method_without_results_answers_with_an_ack<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "nothing", &[], opts()),
        Ok(vec![])
    );
}

/// The caller learns the method table and refuses an unknown method with everything needed
/// to fix the call.
fn an_unknown_method_fails_naming_the_module_the_method_and_the_known_ones<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "fly", &[], opts()),
        Err(CallError::UnknownMethod {
            module: "calc".into(),
            method: "fly".into(),
            known: CALC_METHODS.into(),
        })
    );
}

/// Arguments of the wrong kind, or missing, are refused with NAK "bad arguments" whose
/// detail names the argument.
fn bad_arguments_are_refused_with_a_nak_naming_the_argument<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    match caller.call_owned("calc", "square", &[Value::Text("seven")], opts()) {
        Err(CallError::Nak {
            module,
            code,
            detail,
        }) => {
            assert_eq!((module.as_str(), code), ("calc", NakCode::BAD_ARGUMENTS));
            assert!(detail.contains("argument 0"), "{detail}");
            assert!(detail.contains("text"), "{detail}");
        }
        other => panic!("expected a NAK bad arguments, got {other:?}"),
    }
    match caller.call_owned("calc", "square", &[], opts()) {
        Err(CallError::Nak { code, detail, .. }) => {
            assert_eq!(code, NakCode::BAD_ARGUMENTS);
            assert!(detail.contains("argument 0 is missing"), "{detail}");
        }
        other => panic!("expected a NAK bad arguments, got {other:?}"),
    }
}

/// `MethodError::Busy` reaches the caller as NAK "busy" with the method's words.
fn a_busy_method_answers_with_a_nak_busy<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "busy", &[], opts()),
        Err(CallError::Nak {
            module: "calc".into(),
            code: NakCode::BUSY,
            detail: "the arm is moving".into(),
        })
    );
}

/// A name no module has fails at once.
fn an_unknown_module_name_fails_with_unknown_module<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("nobody", "square", &[Value::I64(1)], opts()),
        Err(CallError::UnknownModule("nobody".into()))
    );
}

/// Twenty calls to two modules are started before any answer is read; each answer reaches
/// `on_done` with the handle of its own call (answers are matched by peer and sequence, and
/// the two peers use the same sequence numbers).
fn twenty_calls_outstanding_at_once_are_each_matched_to_their_answer<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("calc", 3, Calc::tagged(0), calc);
    fx.start("calc2", 4, Calc::tagged(1000), calc);
    let mut caller = fx.caller();
    let mut expected = HashMap::new();
    for i in 0..20i64 {
        let (module, tag) = if i % 2 == 0 {
            ("calc", 0)
        } else {
            ("calc2", 1000)
        };
        let handle = caller
            .ctx()
            .call(module, "square", &[Value::I64(i)])
            .expect("the call starts");
        expected.insert(handle, i * i + tag);
    }
    assert_eq!(expected.len(), 20, "every call has a handle of its own");
    assert!(
        caller.state().answers.is_empty(),
        "no answer was read before all calls were out"
    );
    let all = pump(&mut caller, PATIENCE, |m| m.state().answers.len() >= 20);
    let answers = &caller.state().answers;
    assert!(
        all,
        "only {} of 20 answers came: {answers:?}",
        answers.len()
    );
    for (handle, result) in answers {
        let want = expected.remove(handle).unwrap_or_else(|| {
            panic!("an answer for an unknown or already answered call: {handle:?}")
        });
        assert_eq!(result, &Ok(i64s(&[want])), "answer to call {handle:?}");
    }
}

/// A module that holds its thread does not answer: the call times out after its timeout (not
/// before, and not long after: the stall lasts until the test ends it), naming the module and
/// the caller's timeout; the late answer is not taken for the next call.
fn a_call_to_a_module_that_does_not_answer_times_out<B: Backend>(fx: &mut TestDomain<B>) {
    let (held, began, release) = Calc::held();
    fx.start("calc", 3, held, calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "nothing", &[], opts()),
        Ok(vec![])
    );
    let t = Instant::now();
    let sut = caller.call_owned(
        "calc",
        "stall",
        &[Value::I64(HELD)],
        CallOptions::timeout(Duration::from_millis(250)),
    );
    let waited = t.elapsed();
    match sut {
        Err(CallError::Timeout {
            module, timeout_ms, ..
        }) => assert_eq!((module.as_str(), timeout_ms), ("calc", 250)),
        other => panic!("expected a timeout, got {other:?}"),
    }
    assert!(
        began.recv_timeout(PATIENCE).is_ok(),
        "the module never began the stall"
    );
    assert!(
        waited >= Duration::from_millis(250) && waited < Duration::from_secs(10),
        "gave up after {waited:?}, with a timeout of 250 ms"
    );
    release.send(()).expect("the module holds the stall");
    assert_eq!(
        caller.call_owned("calc", "square", &[Value::I64(7)], opts()),
        Ok(i64s(&[49])),
        "once the module serves again, the next call gets its own answer"
    );
}

/// While a module does not serve, its inbox fills up; then frames to it are refused and the
/// sender learns it (nothing is dropped silently). A call made with `wait_for_peer` goes
/// through once the module serves again.
fn a_full_inbox_refuses_frames_and_the_sender_learns_it<B: Backend>(fx: &mut TestDomain<B>) {
    let (held, began, release) = Calc::held();
    fx.start("calc", 3, held, calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "nothing", &[], opts()),
        Ok(vec![])
    );
    caller
        .ctx()
        .call_with(
            "calc",
            "stall",
            &[Value::I64(HELD)],
            opts().with_retry(RetryPolicy::NONE),
        )
        .expect("the stall call goes out");
    assert!(
        began.recv_timeout(PATIENCE).is_ok(),
        "the module never began the stall"
    );
    let mut delivered = 0;
    let refused = loop {
        match caller.ctx().report_to("calc", 5, &[Value::I64(delivered)]) {
            Ok(()) => delivered += 1,
            Err(e) => break e,
        }
        assert!(delivered < 1000, "the inbox never filled up");
    };
    match refused {
        CallError::NotAvailable { name, why } => {
            assert_eq!(name, "calc");
            assert!(why.contains("inbox is full"), "{why}");
        }
        other => panic!("expected a full inbox, got {other:?}"),
    }
    assert!(
        (32..=64).contains(&delivered),
        "{delivered} frames fit in the inbox"
    );
    assert!(
        caller.ctx().dropped() >= 1,
        "the refused frame is counted as dropped"
    );
    release.send(()).expect("the module holds the stall");
    let waiting = CallOptions {
        wait_for_peer: true,
        ..opts()
    };
    assert_eq!(
        caller.call_owned("calc", "square", &[Value::I64(6)], waiting),
        Ok(i64s(&[36])),
        "a call that waits for its peer goes through once the inbox has room"
    );
}

// ---------------------------------------------------------------------------------------------
// Names, addresses, liveness.

fn open_error<B: Backend>(fx: &TestDomain<B>, name: &str, addr: u8) -> TransportError {
    match fx.open(name, addr, ()) {
        Ok(_) => panic!("{name} at {addr} opened, but it should have been refused"),
        Err(ModuleError::Open { source, .. }) => source,
        Err(e) => panic!("{name} at {addr}: unexpected error {e}"),
    }
}

/// While a module lives, its name and its address are its own; once it left, both are free.
fn a_duplicate_name_or_address_is_refused_while_the_first_module_lives<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("arm", 5, Calc::default(), calc);
    match open_error(fx, "arm", 6) {
        TransportError::NameTaken { name, addr, .. } => {
            assert_eq!((name.as_str(), addr), ("arm", Addr(5)));
        }
        other => panic!("expected NameTaken, got {other:?}"),
    }
    match open_error(fx, "leg", 5) {
        TransportError::AddressTaken { addr, holder, .. } => {
            assert_eq!((addr, holder.as_str()), (Addr(5), "arm"));
        }
        other => panic!("expected AddressTaken, got {other:?}"),
    }
    fx.stop("arm");
    let again = fx.open("arm", 6, ()).expect("the name is free again");
    let leg = fx.open("leg", 5, ()).expect("the address is free again");
    drop((again, leg));
}

/// The caller's phone book refreshes when a name is not found: a module started after the
/// caller is found.
fn a_module_started_later_is_found_by_name<B: Backend>(fx: &mut TestDomain<B>) {
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("late", "square", &[Value::I64(2)], opts()),
        Err(CallError::UnknownModule("late".into()))
    );
    fx.start("late", 9, Calc::default(), calc);
    assert_eq!(
        caller.call_owned("late", "square", &[Value::I64(3)], opts()),
        Ok(i64s(&[9]))
    );
}

fn assert_not_available(r: Result<Vec<OwnedValue>, CallError>, module: &str) {
    match r {
        Err(CallError::NotAvailable { name, .. }) => assert_eq!(name, module),
        other => panic!("expected {module} to be not available, got {other:?}"),
    }
}

/// Calls to a dead module fail with NotAvailable, before and after the phone book noticed.
fn a_killed_module_is_not_available<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("victim", 4, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("victim", "square", &[Value::I64(2)], opts()),
        Ok(i64s(&[4]))
    );
    fx.kill("victim");
    let t = Instant::now();
    assert_not_available(
        caller.call_owned("victim", "square", &[Value::I64(3)], opts()),
        "victim",
    );
    assert_failed_at_once(t.elapsed());
    let noticed = pump(&mut caller, PATIENCE, |m| {
        m.ctx().phone_book().lookup("victim").is_err()
    });
    assert!(noticed, "the phone book still lists victim as alive");
    assert_not_available(
        caller.call_owned("victim", "square", &[Value::I64(3)], opts()),
        "victim",
    );
    let listed = caller.list_modules().expect("list");
    assert!(
        listed.iter().all(|p| p.name != "victim" || !p.alive),
        "victim is listed alive: {listed:?}"
    );
}

/// A module restarted at the address and name of a killed one serves, also once what the
/// killed one left behind is gone.
fn a_module_restarted_at_the_address_of_a_killed_one_keeps_serving<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("victim", 4, Calc::tagged(1), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("victim", "square", &[Value::I64(2)], opts()),
        Ok(i64s(&[5]))
    );
    fx.kill("victim");
    fx.start("victim", 4, Calc::tagged(2), calc);
    fx.end_killed();
    let sut = pump(&mut caller, PATIENCE, |m| {
        m.call_owned("victim", "square", &[Value::I64(2)], opts()) == Ok(i64s(&[6]))
    });
    assert!(
        sut,
        "the restarted victim does not answer: {:?}; listed: {:?}",
        caller.call_owned("victim", "square", &[Value::I64(2)], opts()),
        fx.listed()
    );
}

/// A call that waits for its answer fails as soon as the phone book sees the module die,
/// not after its (long) timeout.
fn a_call_waiting_on_a_module_that_crashes_fails_without_waiting_for_its_timeout<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "nothing", &[], opts()),
        Ok(vec![])
    );
    let t = Instant::now();
    let sut = caller.call_owned("calc", "crash", &[], opts());
    assert_not_available(sut, "calc");
    assert_failed_at_once(t.elapsed());
    fx.wait_for_end("calc");
}

/// Without `wait_for_peer`, a call to a module that is down fails at once.
fn a_call_to_a_module_that_is_down_fails_at_once<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("arm", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("arm", "square", &[Value::I64(3)], opts()),
        Ok(i64s(&[9]))
    );
    fx.kill("arm");
    let t = Instant::now();
    assert_not_available(
        caller.call_owned("arm", "square", &[Value::I64(4)], opts()),
        "arm",
    );
    assert_failed_at_once(t.elapsed());
}

/// With `wait_for_peer`, a call to a module that is down (and known to be down) waits, and is
/// answered once the module is back within the deadline.
fn a_call_that_waits_for_its_peer_succeeds_once_the_peer_is_back<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    call_waiting_for_a_peer_that_comes_back(fx, true);
}

/// The same, when the caller has not noticed yet that the module died: the call goes out,
/// finds no one, and waits until the module is back.
fn a_call_that_waits_for_a_peer_that_just_died_succeeds_once_the_peer_is_back<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    call_waiting_for_a_peer_that_comes_back(fx, false);
}

fn call_waiting_for_a_peer_that_comes_back<B: Backend>(fx: &mut TestDomain<B>, noticed: bool) {
    fx.start("arm", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("arm", "square", &[Value::I64(3)], opts()),
        Ok(i64s(&[9]))
    );
    fx.kill("arm");
    if noticed {
        let seen = pump(&mut caller, PATIENCE, |m| {
            m.ctx().phone_book().lookup("arm").is_err()
        });
        assert!(seen, "the caller never saw arm go down");
    }
    // Taken before arm's thread starts: it opens the module 400 ms later at the earliest.
    let t = Instant::now();
    fx.start_later(Duration::from_millis(400), "arm", 3, Calc::default(), calc);
    let sut = caller.call_owned(
        "arm",
        "square",
        &[Value::I64(5)],
        CallOptions {
            wait_for_peer: true,
            ..opts()
        },
    );
    assert_eq!(sut, Ok(i64s(&[25])), "after {:?}", t.elapsed());
    assert!(
        t.elapsed() >= Duration::from_millis(400),
        "answered after {:?}, before arm was back",
        t.elapsed()
    );
}

// ---------------------------------------------------------------------------------------------
// Reports: broadcast and multicast.

/// Collects what `rx` hears on `topic` until `until` holds (or [`PATIENCE`] passes), then for
/// `quiet` longer, to catch what should not come.
fn collect(
    rx: &mpsc::Receiver<Heard>,
    topic: u8,
    quiet: Duration,
    mut until: impl FnMut(&[Heard]) -> bool,
) -> Vec<Heard> {
    let mut got = Vec::new();
    let deadline = Instant::now() + PATIENCE;
    while !until(&got) && Instant::now() < deadline {
        if let Ok(h) = rx.recv_timeout(Duration::from_millis(10)) {
            got.extend(Some(h).filter(|h| h.topic == topic));
        }
    }
    let end = Instant::now() + quiet;
    while let Some(left) = end.checked_duration_since(Instant::now()) {
        if let Ok(h) = rx.recv_timeout(left) {
            got.extend(Some(h).filter(|h| h.topic == topic));
        }
    }
    got
}

fn names(heard: &[Heard]) -> Vec<&str> {
    let mut v: Vec<&str> = heard.iter().map(|h| h.by.as_str()).collect();
    v.sort_unstable();
    v
}

/// Starts modules a (no group), b and c (group "g") and d (group "h"), each recording what
/// it hears; returns where their records arrive.
fn start_four_ears<B: Backend>(fx: &mut TestDomain<B>) -> mpsc::Receiver<Heard> {
    let (tx, rx) = mpsc::channel();
    for (name, addr, group) in [
        ("a", 3, None),
        ("b", 4, Some("g")),
        ("c", 5, Some("g")),
        ("d", 6, Some("h")),
    ] {
        let heard = tx.clone();
        fx.start(name, addr, Ear { heard }, move |b| {
            let b = ear(b);
            match group {
                Some(g) => b.group(g),
                None => b,
            }
        });
    }
    rx
}

/// A REPORT to `Dest::Broadcast` reaches every other module once, with its sender and values.
fn a_broadcast_reaches_every_other_module<B: Backend>(fx: &mut TestDomain<B>) {
    let rx = start_four_ears(fx);
    let mut caller = fx.caller();
    caller
        .ctx()
        .report(
            Dest::Broadcast,
            7,
            &[Value::Text("hello all"), Value::I64(1)],
        )
        .expect("the broadcast goes out");
    let got = collect(&rx, 7, Duration::from_millis(150), |h| h.len() >= 4);
    assert_eq!(names(&got), ["a", "b", "c", "d"], "{got:#?}");
    for h in &got {
        assert_eq!(h.from, caller.addr());
        assert_eq!(
            h.values,
            vec![OwnedValue::Text("hello all".into()), OwnedValue::I64(1)]
        );
    }
}

/// The sender of a broadcast is not among its receivers.
fn a_module_does_not_hear_its_own_broadcast<B: Backend>(fx: &mut TestDomain<B>) {
    let (tx, rx) = mpsc::channel();
    fx.start("a", 3, Ear { heard: tx.clone() }, ear);
    fx.start("b", 4, Ear { heard: tx }, ear);
    let mut caller = fx.caller();
    assert_eq!(caller.call_owned("a", "shout", &[], opts()), Ok(vec![]));
    let got = collect(&rx, SHOUT_TOPIC, Duration::from_millis(200), |h| {
        h.iter().any(|h| h.by == "b")
    });
    assert_eq!(names(&got), ["b"], "{got:#?}");
    let heard_by_caller = pump(&mut caller, PATIENCE, |m| {
        m.state().heard.iter().any(|h| h.topic == SHOUT_TOPIC)
    });
    assert!(heard_by_caller, "the caller did not hear a's broadcast");
}

/// A REPORT to `Dest::Group("g")` reaches exactly the members of "g".
fn a_multicast_reaches_exactly_the_members_of_its_group<B: Backend>(fx: &mut TestDomain<B>) {
    let rx = start_four_ears(fx);
    let mut caller = fx.caller();
    caller
        .ctx()
        .report(Dest::Group("g"), 8, &[Value::Text("g only")])
        .expect("the multicast goes out");
    let got = collect(&rx, 8, Duration::from_millis(300), |h| h.len() >= 2);
    assert_eq!(names(&got), ["b", "c"], "{got:#?}");
    assert!(got
        .iter()
        .all(|h| h.from == caller.addr() && h.values == vec![OwnedValue::Text("g only".into())]));
    caller
        .ctx()
        .report(Dest::Group("h"), 8, &[Value::Text("h only")])
        .expect("the multicast goes out");
    let got = collect(&rx, 8, Duration::from_millis(300), |h| !h.is_empty());
    assert_eq!(names(&got), ["d"], "{got:#?}");
    let heard_by_caller = pump(&mut caller, Duration::from_millis(50), |m| {
        m.state().heard.iter().any(|h| h.topic == 8)
    });
    assert!(
        !heard_by_caller,
        "the caller is in no group but heard a multicast"
    );
}

// ---------------------------------------------------------------------------------------------
// Blackboard.

/// Snapshots read in place show `a` and `b`, written together, always equal; they come in
/// order and keep coming.
fn snapshots_read_in_place_are_never_torn<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("store", 3, Store::default(), store);
    let mut caller = fx.caller();
    let mut seqs = BTreeSet::new();
    let (mut last_seq, mut last_a) = (0, 0);
    let mut reads = 0;
    let t = Instant::now();
    // Reads for 400 ms at least, until 5 snapshots came and one was read more than once.
    while t.elapsed() < Duration::from_millis(400) || seqs.len() < 5 || reads <= seqs.len() {
        assert!(
            t.elapsed() < PATIENCE,
            "only {} snapshots seen in {reads} reads",
            seqs.len()
        );
        let read = caller
            .ctx()
            .snapshot_of("store", |v| {
                let item = |name| v.value(name).map(|x| x.to_owned_value());
                (v.seq(), item("a"), item("b"))
            })
            .expect("store is known");
        if let Some((seq, a, b)) = read {
            reads += 1;
            let (Ok(OwnedValue::I64(a)), Ok(OwnedValue::I64(b))) = (&a, &b) else {
                panic!("snapshot {seq}: a = {a:?}, b = {b:?}");
            };
            let (a, b) = (*a, *b);
            assert_eq!(a, b, "snapshot {seq} is torn");
            assert!(
                seq >= last_seq && a >= last_a,
                "snapshot {seq} (a = {a}) after {last_seq} (a = {last_a})"
            );
            (last_seq, last_a) = (seq, a);
            seqs.insert(seq);
        }
        std::thread::sleep(Duration::from_micros(200));
    }
    assert!(reads > seqs.len(), "the newest snapshot can be read again");
}

fn bb_get(
    caller: &mut modbot_core::Module<support::Caller>,
    item: &str,
) -> Result<Vec<OwnedValue>, CallError> {
    caller.call_owned("store", "bb_get", &[Value::Text(item)], opts())
}

fn bb_set(
    caller: &mut modbot_core::Module<support::Caller>,
    item: &str,
    v: Value<'_>,
) -> Result<Vec<OwnedValue>, CallError> {
    caller.call_owned("store", "bb_set", &[Value::Text(item), v], opts())
}

fn nak_detail(r: Result<Vec<OwnedValue>, CallError>) -> (NakCode, String) {
    match r {
        Err(CallError::Nak {
            module,
            code,
            detail,
        }) => {
            assert_eq!(module, "store");
            (code, detail)
        }
        other => panic!("expected a NAK, got {other:?}"),
    }
}

/// `bb_get` and `bb_set` (what `modbot bb` uses) read and write items by message; the
/// snapshot shows the write; refusals say why.
fn blackboard_items_are_read_and_written_by_message<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("store", 3, Store::default(), store);
    let mut caller = fx.caller();
    assert_eq!(bb_get(&mut caller, "gain"), Ok(vec![OwnedValue::F64(1.0)]));
    assert_eq!(bb_set(&mut caller, "gain", Value::F64(2.5)), Ok(vec![]));
    assert_eq!(bb_get(&mut caller, "gain"), Ok(vec![OwnedValue::F64(2.5)]));
    assert!(
        eventually(PATIENCE, || {
            caller
                .ctx()
                .snapshot_of("store", |v| v.f64("gain"))
                .ok()
                .flatten()
                == Some(Ok(2.5))
        }),
        "the snapshot never showed the new gain"
    );

    let (_, detail) = nak_detail(bb_set(&mut caller, "a", Value::I64(5)));
    assert!(
        detail.contains("'a'") && detail.contains("read-only"),
        "{detail}"
    );
    let (_, detail) = nak_detail(bb_get(&mut caller, "nope"));
    assert!(
        detail.contains("no blackboard item named 'nope'"),
        "{detail}"
    );
    let (_, detail) = nak_detail(bb_set(&mut caller, "gain", Value::Text("fast")));
    assert!(detail.contains("'gain' is f64"), "{detail}");
    let (_, detail) = nak_detail(bb_set(&mut caller, "limit", Value::F64(2.0)));
    assert!(
        detail.contains("refused") && detail.contains("above the maximum"),
        "{detail}"
    );

    // `modbot bb store`: the whole blackboard in one answer, in the snapshot format.
    let whole = caller.call_blocking("store", "bb_snapshot", &[], opts(), |r| {
        let bytes = r
            .expect("bb_snapshot answers")
            .bytes(0)
            .expect("one bytes value");
        let view = SnapshotView::parse(bytes).expect("a valid snapshot");
        let items: Vec<(String, OwnedValue, bool)> = view
            .iter()
            .map(|i| (i.name.to_owned(), i.value.to_owned_value(), i.writable))
            .collect();
        (view.addr(), items)
    });
    assert_eq!(whole.0, Addr(3));
    let item = |name: &str| whole.1.iter().find(|i| i.0 == name).cloned();
    assert_eq!(
        item("gain"),
        Some(("gain".into(), OwnedValue::F64(2.5), true))
    );
    let (Some((_, a, false)), Some((_, b, false))) = (item("a"), item("b")) else {
        panic!("a and b are read-only items: {whole:?}");
    };
    assert_eq!(a, b, "the snapshot answer is torn");

    let Ok(first) = bb_get(&mut caller, "temp") else {
        panic!("temp is readable")
    };
    let Ok(second) = bb_get(&mut caller, "temp") else {
        panic!("temp is readable")
    };
    assert_eq!(
        (first, second),
        (vec![OwnedValue::F64(21.0)], vec![OwnedValue::F64(22.0)]),
        "the device is sampled on every read"
    );
}

/// A write that the device refuses does not change the item.
fn a_refused_device_write_leaves_the_item_unchanged<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("store", 3, Store::default(), store);
    let mut caller = fx.caller();
    assert_eq!(bb_set(&mut caller, "limit", Value::F64(0.75)), Ok(vec![]));
    let (_, detail) = nak_detail(bb_set(&mut caller, "limit", Value::F64(2.0)));
    assert!(detail.contains("refused"), "{detail}");
    assert_eq!(
        bb_get(&mut caller, "limit"),
        Ok(vec![OwnedValue::F64(0.75)])
    );
}

/// `bb_set` refusals carry the NAK codes `sysmethod::BB_SET` documents: "read-only",
/// "unknown item".
fn bb_set_refusals_carry_the_read_only_and_unknown_item_codes<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("store", 3, Store::default(), store);
    let mut caller = fx.caller();
    let (code, _) = nak_detail(bb_set(&mut caller, "a", Value::I64(5)));
    assert_eq!(code, NakCode::READ_ONLY);
    let (code, _) = nak_detail(bb_set(&mut caller, "nope", Value::I64(5)));
    assert_eq!(code, NakCode::UNKNOWN_ITEM);
}

// ---------------------------------------------------------------------------------------------
// Untrusted frames.

/// The `rejected` counter a module reports in its `describe` answer.
fn rejected(caller: &mut modbot_core::Module<support::Caller>, module: &str) -> i64 {
    let d = caller
        .call_owned(module, "describe", &[], opts())
        .expect("describe");
    match d.get(6) {
        Some(OwnedValue::I64(n)) => *n,
        other => panic!("describe has no rejected count: {other:?}"),
    }
}

/// Garbage sent straight through the transport is dropped and counted; well-formed requests
/// for unknown methods or with undecodable arguments get NAKs; the module keeps serving.
fn malformed_frames_are_counted_as_rejected_and_the_module_keeps_serving<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    fx.start("calc", 3, Calc::default(), calc);
    let mut caller = fx.caller();
    let before = rejected(&mut caller, "calc");
    let mut noise = fx
        .transport
        .open(Addr(200), "noise", ReceiveMode::Blocking, &Joins::NONE)
        .expect("a raw endpoint opens");
    let (to, me) = (3u8, 200u8);
    let exec = |dst: u8, seq: u8, method: u8| FrameSpec {
        dst: Addr(dst),
        src: Addr(me),
        seq: Seq::new(seq).unwrap(),
        kind: FrameKind::Exec { method },
    };
    let garbage: Vec<(&str, Vec<u8>)> = vec![
        ("one byte", vec![to]),
        ("unknown kind", vec![to, me, 7 << 5]),
        ("source 0", vec![to, 0, 1 << 5, 1, 0]),
        ("length mismatch", vec![to, me, 1 << 5, 10, 0]),
        ("ack with a body", vec![to, me, 0, 9]),
        ("exec without its method", vec![to, me, 1 << 5, 0]),
        (
            "for another module",
            exec(77, 0, 3).to_vec(&[Value::I64(2)]).unwrap(),
        ),
    ];
    for (what, bytes) in &garbage {
        noise
            .tx
            .send(Dest::Module(Addr(to)), bytes.len(), &mut |buf| {
                buf.copy_from_slice(bytes)
            })
            .unwrap_or_else(|e| panic!("{what}: not sent: {e}"));
    }
    let unknown = exec(to, 1, 200).to_vec(&[]).unwrap();
    let spec = exec(to, 2, 3);
    let mut undecodable = vec![0; spec.encoded_len(1)];
    spec.encode(&[0xc1], &mut undecodable).unwrap();
    for bytes in [&unknown, &undecodable] {
        noise
            .tx
            .send(Dest::Module(Addr(to)), bytes.len(), &mut |buf| {
                buf.copy_from_slice(bytes)
            })
            .expect("sent");
    }

    let mut naks = HashMap::new();
    let deadline = Instant::now() + PATIENCE;
    while naks.len() < 2 && Instant::now() < deadline {
        let got = noise
            .rx
            .try_receive(&mut |bytes| {
                let f = Frame::decode(bytes).expect("modules send well-formed frames");
                if let (FrameKind::Nak { code }, true) = (f.kind(), f.src() == Addr(to)) {
                    let detail = match f.values().next() {
                        Some(Ok(Value::Text(t))) => t.to_owned(),
                        _ => String::new(),
                    };
                    naks.insert(f.seq().get(), (code, detail));
                }
            })
            .expect("receive");
        if !got {
            let _ = noise.rx.wait(Duration::from_millis(5));
        }
    }
    let (code, detail) = naks.get(&1).expect("a NAK for the unknown method id");
    assert_eq!(*code, NakCode::UNKNOWN_METHOD);
    assert!(
        detail.contains("200") && detail.contains(CALC_METHODS),
        "{detail}"
    );
    let (code, _) = naks.get(&2).expect("a NAK for the undecodable arguments");
    assert_eq!(*code, NakCode::BAD_ARGUMENTS);
    drop(noise);

    assert_eq!(
        rejected(&mut caller, "calc") - before,
        garbage.len() as i64,
        "every malformed or misrouted frame is counted"
    );
    assert_eq!(
        caller.call_owned("calc", "square", &[Value::I64(9)], opts()),
        Ok(i64s(&[81]))
    );
}

// ---------------------------------------------------------------------------------------------
// Statistics and operator activation.

/// A module with a periodic task that counts (`n` on its blackboard and `count()`), and a hook
/// that records the operator's activation changes (`active`, `switches`).
#[derive(Debug, Default)]
struct Ticker {
    n: i64,
    switches: i64,
}

fn ticker(b: ModuleBuilder<Ticker>) -> ModuleBuilder<Ticker> {
    let bb = Blackboard::builder()
        .item("n", OwnedValue::I64(0))
        .item("active", OwnedValue::Bool(true))
        .item("switches", OwnedValue::I64(0))
        .build()
        .expect("a valid blackboard");
    b.blackboard(bb)
        .snapshot_period(Duration::from_millis(20))
        .method("count", count)
        .every(Duration::from_millis(2), tick)
        .on_activation(switched)
}

fn tick(s: &mut Ticker, ctx: &mut Ctx) {
    s.n += 1;
    ctx.bb.write("n", Value::I64(s.n)).expect("n is an i64");
}

fn count(s: &mut Ticker, _: &mut Ctx, _: &Args<'_>, r: &mut Reply) -> Result<(), MethodError> {
    r.push(Value::I64(s.n));
    Ok(())
}

fn switched(s: &mut Ticker, ctx: &mut Ctx, active: bool) {
    assert_eq!(ctx.is_active(), active, "the hook runs after the change");
    s.switches += 1;
    ctx.bb
        .write("active", Value::Bool(active))
        .expect("active is a bool");
    ctx.bb
        .write("switches", Value::I64(s.switches))
        .expect("switches is an i64");
}

/// The `stats` answer of `module`.
fn stats_of(caller: &mut Module<support::Caller>, module: &str) -> Stats {
    caller.call_blocking(module, "stats", &[], opts(), |r| {
        Stats::from_answer(r.expect("stats answers")).expect("a valid stats answer")
    })
}

/// A module counts the frames it sends and receives and the calls it makes; each answered
/// call's latency goes into its histogram (a NAK is an answer, a timeout is not). `stats`
/// answers the same counters for any module.
fn stats_count_frames_and_calls_and_record_the_latency_of_each_answered_call<B: Backend>(
    fx: &mut TestDomain<B>,
) {
    const N: u64 = 20;
    let (held, _, release) = Calc::held();
    fx.start("calc", 3, held, calc);
    let mut caller = fx.caller();
    for i in 0..N as i64 {
        assert_eq!(
            caller.call_owned("calc", "square", &[Value::I64(i)], opts()),
            Ok(i64s(&[i * i]))
        );
    }
    let sut = caller.ctx().stats().clone();
    assert_eq!((sut.calls, sut.answered, sut.failed), (N, N, 0), "{sut:?}");
    assert_eq!(sut.latency.count(), N);
    let (p50, p99) = (sut.latency.percentile(50.0), sut.latency.percentile(99.0));
    assert!(0 < p50 && p50 <= p99 && p99 <= sut.latency.max(), "{sut:?}");
    assert!(
        u128::from(sut.latency.max()) < CALL_TIMEOUT.as_nanos(),
        "no answer took longer than the timeout: {sut:?}"
    );
    // N requests and a `describe` out, their answers back.
    assert!(sut.frames_sent > N && sut.frames_received > N, "{sut:?}");

    let served = stats_of(&mut caller, "calc");
    assert!(
        served.frames_received >= N + 2,
        "describe, N requests and stats received: {served:?}"
    );
    assert!(served.frames_sent > N, "{served:?}");
    assert_eq!(
        (served.calls, served.latency.count()),
        (0, 0),
        "calc made no call"
    );

    // Refused: answered by a NAK, so failed, but its latency counts.
    assert!(caller.call_owned("calc", "busy", &[], opts()).is_err());
    // Timed out (the stall lasts until the test ends it): failed, no latency.
    let hasty = CallOptions::timeout(Duration::from_millis(100)).with_retry(RetryPolicy::NONE);
    assert!(matches!(
        caller.call_owned("calc", "stall", &[Value::I64(HELD)], hasty),
        Err(CallError::Timeout { .. })
    ));
    release.send(()).expect("the module holds the stall");
    let sut = caller.ctx().stats().clone();
    assert_eq!(
        (sut.calls, sut.answered, sut.failed),
        (N + 3, N + 1, 2),
        "the stats call answered, busy and stall failed: {sut:?}"
    );
    assert_eq!(sut.latency.count(), N + 2);

    let later = stats_of(&mut caller, "calc");
    assert!(
        later.frames_received > served.frames_received && later.frames_sent > served.frames_sent,
        "{served:?} then {later:?}"
    );
}

/// `deactivate` makes a module refuse its own methods with NAK not-ready and pause its tasks;
/// its system methods and snapshots go on; `activate` brings it back. The hook hears each
/// change once.
fn an_operator_can_deactivate_a_module_and_activate_it_again<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("ticker", 3, Ticker::default(), ticker);
    let mut caller = fx.caller();
    let item = |caller: &mut Module<support::Caller>, name: &str| -> OwnedValue {
        let mut got = caller
            .call_owned("ticker", "bb_get", &[Value::Text(name)], opts())
            .unwrap_or_else(|e| panic!("bb_get {name}: {e}"));
        assert_eq!(got.len(), 1);
        got.remove(0)
    };
    let n = |v: OwnedValue| match v {
        OwnedValue::I64(n) => n,
        other => panic!("n is {other:?}"),
    };
    assert!(eventually(PATIENCE, || n(item(&mut caller, "n")) > 2));
    assert!(caller.call_owned("ticker", "count", &[], opts()).is_ok());

    assert_eq!(
        caller.call_owned("ticker", "deactivate", &[], opts()),
        Ok(vec![])
    );
    assert_eq!(
        caller.call_owned("ticker", "count", &[], opts()),
        Err(CallError::Nak {
            module: "ticker".into(),
            code: NakCode::NOT_READY,
            detail: "module 'ticker' is deactivated by the operator".into(),
        })
    );
    let paused = n(item(&mut caller, "n"));
    std::thread::sleep(Duration::from_millis(60));
    assert_eq!(n(item(&mut caller, "n")), paused, "the task is paused");
    assert_eq!(item(&mut caller, "active"), OwnedValue::Bool(false));
    assert_eq!(item(&mut caller, "switches"), OwnedValue::I64(1));
    let described = caller
        .call_owned("ticker", "describe", &[], opts())
        .expect("describe answers while deactivated");
    assert_eq!(described.get(8), Some(&OwnedValue::Bool(false)));
    assert!(stats_of(&mut caller, "ticker").frames_received > 0);
    assert!(
        eventually(PATIENCE, || {
            caller
                .ctx()
                .snapshot_of("ticker", |v| v.bool("active"))
                .ok()
                .flatten()
                == Some(Ok(false))
        }),
        "snapshots go on while deactivated"
    );
    assert_eq!(
        caller.call_owned("ticker", "deactivate", &[], opts()),
        Ok(vec![])
    );
    assert_eq!(
        item(&mut caller, "switches"),
        OwnedValue::I64(1),
        "no change, no hook"
    );

    assert_eq!(
        caller.call_owned("ticker", "activate", &[], opts()),
        Ok(vec![])
    );
    assert!(caller.call_owned("ticker", "count", &[], opts()).is_ok());
    assert!(
        eventually(PATIENCE, || n(item(&mut caller, "n")) > paused),
        "the task runs again"
    );
    assert_eq!(item(&mut caller, "active"), OwnedValue::Bool(true));
    assert_eq!(item(&mut caller, "switches"), OwnedValue::I64(2));
}

/// A module's own method cannot take a system method's name: callers could never reach it.
fn a_method_named_like_a_system_method_is_refused_at_open<B: Backend>(fx: &mut TestDomain<B>) {
    let sut = ModuleBuilder::new("shadow", 5)
        .method("stats", nothing)
        .open(fx.transport.clone(), Calc::default());
    match sut {
        Err(ModuleError::Definition(why)) => assert!(why.contains("'stats'"), "{why}"),
        Err(e) => panic!("expected a definition error, got {e}"),
        Ok(_) => panic!("a method named stats was accepted"),
    }
}

// ---------------------------------------------------------------------------------------------
// Receive modes, listing, cleanup.

/// A busy-poll module answers like a blocking one, and the directory lists each module with
/// its address, name, mode and liveness.
fn a_busy_poll_module_answers_and_is_listed_with_its_mode<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("spinner", 3, Calc::tagged(1), |b| {
        calc(b).mode(ReceiveMode::BusyPoll)
    });
    fx.start("sleeper", 4, Calc::tagged(2), calc);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("spinner", "square", &[Value::I64(3)], opts()),
        Ok(i64s(&[10]))
    );
    assert_eq!(
        caller.call_owned("sleeper", "square", &[Value::I64(3)], opts()),
        Ok(i64s(&[11]))
    );
    let listed: Vec<_> = caller
        .list_modules()
        .expect("list")
        .into_iter()
        .map(|p| (p.addr, p.name, p.mode, p.alive))
        .collect();
    let me = caller.addr();
    assert_eq!(listed.len(), 3, "{listed:?}");
    assert_eq!(
        listed[0],
        (Addr(3), "spinner".into(), ReceiveMode::BusyPoll, true)
    );
    assert_eq!(
        listed[1],
        (Addr(4), "sleeper".into(), ReceiveMode::Blocking, true)
    );
    assert_eq!((listed[2].0, listed[2].3), (me, true));
    assert!(listed[2].1.starts_with("tester-"), "{listed:?}");
}

/// The domain's files stay while any module lives, and the last one to leave removes them
/// all (no module listed, nothing in `/dev/shm` or `/tmp/iceoryx2`).
fn the_last_module_to_leave_removes_the_domains_files<B: Backend>(fx: &mut TestDomain<B>) {
    fx.start("calc", 3, Calc::default(), calc);
    fx.start("store", 4, Store::default(), store);
    let mut caller = fx.caller();
    assert_eq!(
        caller.call_owned("calc", "square", &[Value::I64(2)], opts()),
        Ok(i64s(&[4]))
    );
    assert_eq!(bb_get(&mut caller, "gain"), Ok(vec![OwnedValue::F64(1.0)]));
    assert!(caller.ctx().snapshot_of("store", |_| ()).is_ok());
    fx.stop("calc");
    fx.stop("store");
    if B::SHARED_MEMORY {
        assert!(
            !fx.domain.files().is_empty(),
            "files vanished while the caller lives"
        );
    }
    assert_eq!(fx.listed().len(), 1, "{:?}", fx.listed());
    drop(caller);
    fx.assert_empty();
}
