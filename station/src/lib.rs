//! modbot-station: the operator's control station, a web page served from inside a domain.
//!
//! `modbot station --domain D [--listen 127.0.0.1:8080] [--token T]` joins the domain as a
//! tool (at a free address, or through the supervisor's relay when a full system has none) and
//! serves a page whose live view comes over a WebSocket. Two halves, joined by channels:
//!
//! - [`watcher`]: one thread owns the domain's endpoint. Ten times a second it asks the
//!   supervisor for its status rows, the coordinator for its ledger, the bus bridge for the
//!   robot's state, and the watched modules for their blackboards; once a second every module
//!   for what it says of itself (active, methods, counters, latency). What it sees becomes one
//!   [`state::State`], serialised once and handed to every browser through a latest-value
//!   channel: a slow browser skips updates, it never holds up the watcher, and the watcher
//!   never holds up a module. Commands from the page come in over a queue and are run between
//!   looks, each answered with its result or its error.
//! - [`server`]: axum over HTTP/1 — the page's assets (compiled into the binary from
//!   `station/assets/`: nothing is fetched at run time), `/api/state` and `/api/map` for
//!   scripts, and `/ws`, where a browser gets the state and sends [`commands`].
//!
//! [`top`] is `modbot top`: the same looks as a terminal view (ratatui).
//!
//! [`access`] decides who may command: on loopback anyone; elsewhere only a connection that
//! shows the token (given, or printed at start). [`map`] holds MOSER's building for the page.

pub mod access;
pub mod commands;
pub mod events;
pub mod map;
pub mod server;
pub mod state;
pub mod top;
pub mod watcher;
