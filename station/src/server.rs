//! The web side: the page, the state for scripts, and the WebSocket.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use axum::extract::ws::{CloseFrame, Message as WsMessage, WebSocket, WebSocketUpgrade};
use axum::extract::{Query, State as AxumState};
use axum::http::header;
use axum::response::{IntoResponse, Response};
use axum::routing::get;
use axum::Router;
use crossbeam::channel::Sender;
use serde::Deserialize;
use tokio::sync::{oneshot, watch};

use crate::access::Access;
use crate::commands::{self, Answer, Message};
use crate::watcher::Input;

/// The page's files, compiled in.
const INDEX: &str = include_str!("../assets/index.html");
const SCRIPT: &str = include_str!("../assets/station.js");
const STYLE: &str = include_str!("../assets/station.css");

/// WebSocket close codes (RFC 6455): a message that is not what the protocol allows, and one
/// too big.
const CLOSE_POLICY: u16 = 1008;
const CLOSE_TOO_BIG: u16 = 1009;

/// What every request handler shares.
#[derive(Clone)]
pub struct Shared {
    pub access: Arc<Access>,
    pub states: watch::Receiver<Arc<str>>,
    pub inputs: Sender<Input>,
    pub domain: Arc<str>,
    pub map: Arc<str>,
    /// The pages connected now (the watcher reports it with each look).
    pub pages: Arc<AtomicUsize>,
}

/// Counts a page while its connection lasts.
struct Page(Arc<AtomicUsize>);

impl Page {
    fn new(pages: &Arc<AtomicUsize>) -> Page {
        pages.fetch_add(1, Ordering::Relaxed);
        Page(pages.clone())
    }
}

impl Drop for Page {
    fn drop(&mut self) {
        self.0.fetch_sub(1, Ordering::Relaxed);
    }
}

/// The station's routes.
pub fn router(shared: Shared) -> Router {
    Router::new()
        .route(
            "/",
            get(|| async { page(INDEX, "text/html; charset=utf-8") }),
        )
        .route(
            "/station.js",
            get(|| async { page(SCRIPT, "text/javascript; charset=utf-8") }),
        )
        .route(
            "/station.css",
            get(|| async { page(STYLE, "text/css; charset=utf-8") }),
        )
        .route("/api/state", get(api_state))
        .route("/api/map", get(api_map))
        .route("/ws", get(ws))
        .with_state(shared)
}

fn page(body: &'static str, kind: &'static str) -> Response {
    ([(header::CONTENT_TYPE, kind)], body).into_response()
}

async fn api_state(AxumState(s): AxumState<Shared>) -> Response {
    let json = s.states.borrow().clone();
    (
        [(header::CONTENT_TYPE, "application/json")],
        json.to_string(),
    )
        .into_response()
}

async fn api_map(AxumState(s): AxumState<Shared>) -> Response {
    (
        [(header::CONTENT_TYPE, "application/json")],
        s.map.to_string(),
    )
        .into_response()
}

#[derive(Deserialize)]
struct WsQuery {
    token: Option<String>,
}

async fn ws(
    upgrade: WebSocketUpgrade,
    Query(q): Query<WsQuery>,
    AxumState(s): AxumState<Shared>,
) -> Response {
    let can_command = s.access.may_command(q.token.as_deref());
    upgrade
        .max_message_size(commands::MAX_MESSAGE)
        .max_frame_size(commands::MAX_MESSAGE)
        .on_upgrade(move |socket| connection(socket, s, can_command))
}

/// One browser: the state as it changes (the latest only: a slow browser skips updates), the
/// answers to its commands, and its messages.
async fn connection(mut socket: WebSocket, s: Shared, can_command: bool) {
    let _page = Page::new(&s.pages);
    let hello = serde_json::json!({
        "type": "hello",
        "domain": &*s.domain,
        "can_command": can_command,
    });
    if socket
        .send(WsMessage::Text(hello.to_string().into()))
        .await
        .is_err()
    {
        return;
    }
    let mut states = s.states.clone();
    states.mark_changed();
    let (answers_tx, mut answers) = tokio::sync::mpsc::channel::<Answer>(16);
    loop {
        tokio::select! {
            changed = states.changed() => {
                if changed.is_err() {
                    return close(socket, 1001, "the station stops").await;
                }
                let json = states.borrow_and_update().clone();
                if socket.send(WsMessage::Text(json.to_string().into())).await.is_err() {
                    return;
                }
            }
            Some(answer) = answers.recv() => {
                let text = serde_json::to_string(&answer).unwrap_or_default();
                if socket.send(WsMessage::Text(text.into())).await.is_err() {
                    return;
                }
            }
            incoming = socket.recv() => {
                let text = match incoming {
                    Some(Ok(WsMessage::Text(t))) => t,
                    Some(Ok(WsMessage::Binary(_))) => {
                        return close(socket, CLOSE_POLICY, "binary messages are not understood").await;
                    }
                    Some(Ok(WsMessage::Close(_))) | None => return,
                    Some(Ok(_)) => continue,
                    Some(Err(e)) => {
                        let reason = format!("refused: {e}");
                        return close(socket, CLOSE_TOO_BIG, &reason).await;
                    }
                };
                match commands::parse(text.as_str()) {
                    Ok(Message::Watch(modules)) => {
                        let _ = s.inputs.try_send(Input::Watch(modules));
                    }
                    Ok(Message::Call(call)) if !can_command => {
                        let refused = Answer::err(
                            call.id,
                            "read-only: this page has no valid token, it cannot command".into(),
                        );
                        let _ = answers_tx.try_send(refused);
                    }
                    Ok(Message::Call(call)) => {
                        let (tx, rx) = oneshot::channel();
                        let id = call.id;
                        if s.inputs.try_send(Input::Call(call, tx)).is_err() {
                            let _ = answers_tx.try_send(Answer::err(id, "the station is busy: try again".into()));
                            continue;
                        }
                        let answers_tx = answers_tx.clone();
                        tokio::spawn(async move {
                            let answer = rx.await.unwrap_or_else(|_| {
                                Answer::err(id, "the station's watcher ended".into())
                            });
                            let _ = answers_tx.send(answer).await;
                        });
                    }
                    Err(e) => return close(socket, CLOSE_POLICY, &e.to_string()).await,
                }
            }
        }
    }
}

/// Closes with `code` and `reason` (cut to the 123 bytes a close frame holds).
async fn close(mut socket: WebSocket, code: u16, reason: &str) {
    let mut cut = reason.len().min(123);
    while !reason.is_char_boundary(cut) {
        cut -= 1;
    }
    let frame = CloseFrame {
        code,
        reason: reason[..cut].to_owned().into(),
    };
    let _ = socket.send(WsMessage::Close(Some(frame))).await;
}
