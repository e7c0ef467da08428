//! An inbox has as many sender slots as its creator's configuration says
//! (`MODBOT_INBOX_SENDERS`, which a supervisor sets for its system): every receive looks at
//! each slot, so a system's inboxes are sized to it. A sender beyond them is refused by name,
//! a slot freed by a sender that closed is taken by the next, and a sender configured for more
//! slots opens an inbox created with fewer.

use modbot_ipc_schema::Addr;
use modbot_testkit::TestDomain;
use modbot_transport::ipc::IpcTransport;
use modbot_transport::{Dest, Endpoint, Joins, ReceiveMode, SendError, Transport, TransportError};

fn endpoint(transport: &IpcTransport, addr: u8) -> Endpoint {
    transport
        .open(
            Addr(addr),
            &format!("m{addr}"),
            ReceiveMode::BusyPoll,
            &Joins::NONE,
        )
        .unwrap()
}

fn send(from: &mut Endpoint, to: u8, byte: u8) -> Result<(), SendError> {
    from.tx
        .send(Dest::Module(Addr(to)), 1, &mut |buf| buf[0] = byte)
}

fn received(sut: &mut Endpoint) -> Vec<u8> {
    let mut got = Vec::new();
    while sut.rx.try_receive(&mut |frame| got.push(frame[0])).unwrap() {}
    got
}

#[test]
fn a_sender_beyond_the_inboxs_slots_is_refused_by_name_until_a_slot_frees() {
    let domain = TestDomain::new("slots", "refused");
    let transport = IpcTransport::new(&domain).unwrap().with_inbox_senders(4);
    let mut sut = endpoint(&transport, 1);
    let mut senders: Vec<Endpoint> = (2..=5).map(|a| endpoint(&transport, a)).collect();
    for (i, s) in senders.iter_mut().enumerate() {
        send(s, 1, i as u8).expect("a sender within the inbox's slots");
    }
    let mut fifth = endpoint(&transport, 6);
    let refused = send(&mut fifth, 1, 9).unwrap_err();
    assert_eq!(
        refused,
        SendError::Transport(TransportError::InboxSendersTaken {
            addr: Addr(1),
            slots: 4
        })
    );
    let message = refused.to_string();
    assert!(
        message.contains("module 1's inbox takes 4 senders")
            && message.contains("MODBOT_INBOX_SENDERS"),
        "{message}"
    );
    assert_eq!(
        received(&mut sut),
        [0, 1, 2, 3],
        "the four frames arrived, the refused did not"
    );

    drop(senders.remove(0));
    send(&mut fifth, 1, 9).expect("the slot a closed sender freed");
    assert_eq!(received(&mut sut), [9]);
}

#[test]
fn a_sender_configured_for_more_slots_opens_an_inbox_created_with_fewer() {
    let domain = TestDomain::new("slots", "opener");
    let small = IpcTransport::new(&domain).unwrap().with_inbox_senders(4);
    let mut sut = endpoint(&small, 1);
    let default = IpcTransport::new(&domain).unwrap();
    let mut sender = endpoint(&default, 2);
    send(&mut sender, 1, 7).expect("an opener does not require slots of its own");
    assert_eq!(received(&mut sut), [7]);
}
