//! The channels and wake-ups of both backends keep the same promises: samples in order to
//! every subscriber, the oldest dropped when one is full, history for a late subscriber,
//! publishers counted, and a wake-up that wakes, times out and is taken by a drain.

use std::time::Duration;

use modbot_testkit::TestDomain;
use modbot_transport::channels::{ChannelSpec, Channels};
use modbot_transport::ipc::IpcTransport;
use modbot_transport::local::LocalTransport;

const SPEC: ChannelSpec = ChannelSpec {
    depth: 4,
    history: 0,
    publishers: 2,
    subscribers: 4,
};

/// Runs `test` against the iceoryx2 backend and the in-process one, each in a fresh domain.
fn on_both(name: &str, test: fn(&dyn Channels)) {
    let domain = TestDomain::new("ch", &format!("i_{name}"));
    {
        let ipc = IpcTransport::new(&domain)
            .unwrap()
            .channels("test")
            .unwrap();
        test(&ipc);
    }
    drop(domain);
    let domain = TestDomain::new("ch", &format!("l_{name}"));
    test(&LocalTransport::new(&domain).channels());
}

fn received(sub: &dyn modbot_transport::channels::ByteSubscriber) -> Vec<Vec<u8>> {
    let mut all = Vec::new();
    while sub.receive(&mut |s| all.push(s.to_vec())).unwrap() {}
    all
}

#[test]
fn every_subscriber_receives_every_sample_in_order() {
    on_both("order", |ch| {
        let a = ch.subscriber("c", &SPEC).unwrap();
        let b = ch.subscriber("c", &SPEC).unwrap();
        let publisher = ch.publisher("c", &SPEC, 8).unwrap();
        publisher.send_bytes(&[1, 2]).unwrap();
        publisher
            .send(3, &mut |buf| buf.copy_from_slice(&[3, 4, 5]))
            .unwrap();
        assert_eq!(received(&*a), vec![vec![1, 2], vec![3, 4, 5]]);
        assert_eq!(received(&*b), vec![vec![1, 2], vec![3, 4, 5]]);
        assert!(received(&*a).is_empty());
    });
}

#[test]
fn a_full_subscriber_drops_its_oldest_sample() {
    on_both("full", |ch| {
        let sub = ch.subscriber("c", &SPEC).unwrap();
        let publisher = ch.publisher("c", &SPEC, 1).unwrap();
        for i in 0..6u8 {
            publisher.send_bytes(&[i]).unwrap();
        }
        assert_eq!(received(&*sub), vec![vec![2], vec![3], vec![4], vec![5]]);
    });
}

#[test]
fn a_late_subscriber_receives_the_history_and_no_more() {
    on_both("history", |ch| {
        let spec = ChannelSpec { history: 1, ..SPEC };
        let publisher = ch.publisher("c", &spec, 1).unwrap();
        publisher.send_bytes(&[1]).unwrap();
        publisher.send_bytes(&[2]).unwrap();
        let late = ch.subscriber("c", &spec).unwrap();
        // iceoryx2 hands the history over when the publisher next looks at its connections.
        publisher.send_bytes(&[3]).unwrap();
        assert_eq!(received(&*late), vec![vec![2], vec![3]]);
    });
}

#[test]
fn a_channel_counts_its_publishers() {
    on_both("publishers", |ch| {
        assert_eq!(ch.publishers("c", &SPEC).unwrap(), 0);
        let publisher = ch.publisher("c", &SPEC, 1).unwrap();
        assert_eq!(ch.publishers("c", &SPEC).unwrap(), 1);
        drop(publisher);
        assert_eq!(ch.publishers("c", &SPEC).unwrap(), 0);
    });
}

#[test]
fn a_notification_wakes_the_listener_and_a_drain_takes_it() {
    on_both("wake", |ch| {
        let listener = ch.listener("w", 2).unwrap();
        let notifier = ch.notifier("w", 2).unwrap();
        assert!(
            !listener.wait(Some(Duration::from_micros(300))),
            "a silent listener times out"
        );
        notifier.notify().unwrap();
        assert!(listener.wait(Some(Duration::from_secs(10))));
        listener.drain();
        assert!(
            !listener.wait(Some(Duration::ZERO)),
            "the notification was taken"
        );
        for _ in 0..3 {
            notifier.notify().unwrap();
            assert!(listener.wait(None), "each notification after a drain wakes");
            listener.drain();
        }
    });
}

#[test]
fn a_notification_from_another_thread_ends_a_wait_without_limit() {
    on_both("thread", |ch| {
        let listener = ch.listener("w", 2).unwrap();
        let notifier = ch.notifier("w", 2).unwrap();
        let waker = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(20));
            notifier.notify().unwrap();
        });
        assert!(listener.wait(None));
        waker.join().unwrap();
    });
}
