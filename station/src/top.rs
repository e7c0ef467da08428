//! `modbot top`: the station's system and grid views in a terminal (ratatui), from the same
//! looks as the page ([`crate::watcher::Watcher::look`]).
//!
//! Keys: ↑/↓ choose a module, Enter shows its detail (Esc closes it), `n` `a` `s` `r` `l`
//! sort by name, address, state, restarts or latency p99 (again: reversed), `q` quits.

use std::time::Instant;

use ratatui::crossterm::event::{self, Event, KeyCode, KeyEventKind, KeyModifiers};
use ratatui::layout::{Constraint, Layout, Rect};
use ratatui::style::{Modifier, Style};
use ratatui::text::Line;
use ratatui::widgets::{Block, Clear, Paragraph, Row, Table, TableState};
use ratatui::Frame;

use crate::state::{Module, State};
use crate::watcher::{Watcher, LOOK_PERIOD};

/// What the modules are sorted by.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SortBy {
    Addr,
    Name,
    State,
    Restarts,
    Latency,
}

impl SortBy {
    fn of_key(c: char) -> Option<SortBy> {
        Some(match c {
            'a' => SortBy::Addr,
            'n' => SortBy::Name,
            's' => SortBy::State,
            'r' => SortBy::Restarts,
            'l' => SortBy::Latency,
            _ => return None,
        })
    }

    fn word(self) -> &'static str {
        match self {
            SortBy::Addr => "address",
            SortBy::Name => "name",
            SortBy::State => "state",
            SortBy::Restarts => "restarts",
            SortBy::Latency => "latency p99",
        }
    }
}

/// Sorts `modules` by `by` (reversed if `reverse`); ties by address.
pub fn sort(modules: &mut [Module], by: SortBy, reverse: bool) {
    modules.sort_by(|a, b| {
        let order = match by {
            SortBy::Addr => a.row.addr.cmp(&b.row.addr),
            SortBy::Name => a.row.name.cmp(&b.row.name),
            SortBy::State => a.row.state.cmp(&b.row.state),
            SortBy::Restarts => a.row.restarts.cmp(&b.row.restarts),
            SortBy::Latency => a
                .latency_p99_us
                .unwrap_or(-1.0)
                .total_cmp(&b.latency_p99_us.unwrap_or(-1.0)),
        }
        .then(a.row.addr.cmp(&b.row.addr));
        if reverse {
            order.reverse()
        } else {
            order
        }
    });
}

/// The screen's state between frames.
struct Screen {
    state: State,
    table: TableState,
    by: SortBy,
    reverse: bool,
    detail: bool,
}

/// Runs the terminal view until `q` (or Ctrl-C).
pub fn run(mut watcher: Watcher) -> std::io::Result<()> {
    let mut terminal = ratatui::init();
    let mut screen = Screen {
        state: watcher.look(),
        table: TableState::default().with_selected(Some(0)),
        by: SortBy::Addr,
        reverse: false,
        detail: false,
    };
    let mut next = Instant::now() + LOOK_PERIOD;
    let outcome = loop {
        sort(&mut screen.state.modules, screen.by, screen.reverse);
        if let Err(e) = terminal.draw(|f| draw(f, &mut screen)) {
            break Err(e);
        }
        let wait = next.saturating_duration_since(Instant::now());
        match event::poll(wait) {
            Ok(true) => match event::read() {
                Ok(Event::Key(k)) if k.kind == KeyEventKind::Press => {
                    if !key(&mut screen, k.code, k.modifiers) {
                        break Ok(());
                    }
                }
                Ok(_) => {}
                Err(e) => break Err(e),
            },
            Ok(false) => {}
            Err(e) => break Err(e),
        }
        if Instant::now() >= next {
            screen.state = watcher.look();
            next = Instant::now() + LOOK_PERIOD;
        }
    };
    ratatui::restore();
    outcome
}

/// Handles a key; false: quit.
fn key(s: &mut Screen, code: KeyCode, modifiers: KeyModifiers) -> bool {
    let n = s.state.modules.len();
    match code {
        KeyCode::Char('q') => return false,
        KeyCode::Char('c') if modifiers.contains(KeyModifiers::CONTROL) => return false,
        KeyCode::Esc => s.detail = false,
        KeyCode::Enter => s.detail = !s.detail,
        KeyCode::Down => {
            let i = s.table.selected().unwrap_or(0);
            s.table.select(Some((i + 1).min(n.saturating_sub(1))));
        }
        KeyCode::Up => {
            let i = s.table.selected().unwrap_or(0);
            s.table.select(Some(i.saturating_sub(1)));
        }
        KeyCode::Char(c) => {
            if let Some(by) = SortBy::of_key(c) {
                s.reverse = s.by == by && !s.reverse;
                s.by = by;
            }
        }
        _ => {}
    }
    true
}

fn us(x: Option<f64>) -> String {
    match x {
        None => "-".into(),
        Some(x) if x < 1000.0 => format!("{x:.1} µs"),
        Some(x) => format!("{:.2} ms", x / 1000.0),
    }
}

fn draw(f: &mut Frame, s: &mut Screen) {
    let st = &s.state;
    let grid_rows = st
        .grid
        .as_ref()
        .map_or(0, |g| g.components.len() as u16 + 4);
    let [head, modules, grid, foot] = Layout::vertical([
        Constraint::Length(2),
        Constraint::Min(5),
        Constraint::Length(grid_rows),
        Constraint::Length(1),
    ])
    .areas(f.area());

    let running = st
        .modules
        .iter()
        .filter(|m| m.row.state == "running")
        .count();
    let mut lines = vec![Line::from(format!(
        "modbot top · domain {} · {} modules, {running} running · sorted by {}{}",
        st.domain,
        st.modules.len(),
        s.by.word(),
        if s.reverse { " (reversed)" } else { "" }
    ))];
    lines.push(Line::from(match (&st.robot, &st.grid) {
        (Some(r), _) => format!("robot {r}"),
        (None, Some(g)) => format!("grid {}", g.grid.state),
        (None, None) => st.problems.first().cloned().unwrap_or_default(),
    }));
    f.render_widget(Paragraph::new(lines), head);

    let header = Row::new([
        "ADDR",
        "NAME",
        "STATE",
        "ACTIVE",
        "PID",
        "RESTARTS",
        "BEAT",
        "LAST EXIT",
        "DROPPED",
        "REJECT",
        "CALLS",
        "P50",
        "P99",
    ])
    .style(Style::new().add_modifier(Modifier::BOLD));
    let rows = st.modules.iter().map(|m| {
        Row::new([
            m.row.addr.to_string(),
            m.row.name.clone(),
            m.row.state.clone(),
            match m.active {
                Some(true) => "yes".into(),
                Some(false) => "no".into(),
                None => "?".into(),
            },
            m.row.pid.to_string(),
            m.row.restarts.to_string(),
            beat(m.row.heartbeat_age_ms),
            m.row.last_exit.clone(),
            m.row.counters.dropped.to_string(),
            m.row.counters.rejected.to_string(),
            m.calls.to_string(),
            us(m.latency_p50_us),
            us(m.latency_p99_us),
        ])
    });
    let widths = [
        Constraint::Length(4),
        Constraint::Min(10),
        Constraint::Length(10),
        Constraint::Length(6),
        Constraint::Length(7),
        Constraint::Length(8),
        Constraint::Length(7),
        Constraint::Min(12),
        Constraint::Length(7),
        Constraint::Length(6),
        Constraint::Length(7),
        Constraint::Length(9),
        Constraint::Length(9),
    ];
    let table = Table::new(rows, widths)
        .header(header)
        .block(Block::bordered().title(" modules "))
        .row_highlight_style(Style::new().add_modifier(Modifier::REVERSED));
    f.render_stateful_widget(table, modules, &mut s.table);

    if let Some(g) = &st.grid {
        let assembly = g
            .assembly
            .as_ref()
            .map(|a| format!(" · assembly {} generation {}", a.name, a.generation))
            .unwrap_or_default();
        let title = format!(
            " grid {} · tick {} · missed {} · {:.0} Hz{assembly} ",
            g.grid.state, g.grid.ticks, g.grid.missed, g.grid.rate_hz
        );
        let header = Row::new([
            "COMPONENT",
            "HOST",
            "PERIOD",
            "POLICY",
            "RELEASES",
            "OVERRUNS",
            "LATE",
            "STALE",
            "EXEC P50",
            "EXEC P99",
        ])
        .style(Style::new().add_modifier(Modifier::BOLD));
        let rows = g.components.iter().map(|c| {
            Row::new([
                c.name.clone(),
                c.host.clone(),
                c.period.to_string(),
                c.policy.clone(),
                c.releases.to_string(),
                c.overruns.to_string(),
                c.late.to_string(),
                c.stale.to_string(),
                us(Some(c.exec_p50 as f64 / 1e3)),
                us(Some(c.exec_p99 as f64 / 1e3)),
            ])
        });
        let widths = [Constraint::Min(8); 10];
        f.render_widget(
            Table::new(rows, widths)
                .header(header)
                .block(Block::bordered().title(title)),
            grid,
        );
    }
    f.render_widget(
        Paragraph::new("↑/↓ module · Enter detail · sort: n name, a address, s state, r restarts, l latency · q quit"),
        foot,
    );
    if s.detail {
        if let Some(m) = s.table.selected().and_then(|i| st.modules.get(i)) {
            detail(f, m);
        }
    }
}

/// A heartbeat's age: `120ms`, `3.4s`, or `-` when there is none.
fn beat(ms: Option<u64>) -> String {
    match ms {
        None => "-".to_owned(),
        Some(ms) if ms < 10_000 => format!("{ms}ms"),
        Some(ms) => format!("{:.1}s", ms as f64 / 1e3),
    }
}

/// A module's detail over the table.
fn detail(f: &mut Frame, m: &Module) {
    let area = f.area();
    let popup = Rect {
        x: area.width / 8,
        y: area.height / 6,
        width: area.width * 3 / 4,
        height: (area.height * 2 / 3).max(8),
    }
    .intersection(area);
    let text = vec![
        Line::from(format!("module {} at address {}", m.row.name, m.row.addr)),
        Line::from(format!(
            "state {} · pid {} · restarts {} · last heartbeat {} ago",
            m.row.state,
            m.row.pid,
            m.row.restarts,
            beat(m.row.heartbeat_age_ms)
        )),
        Line::from(format!(
            "last exit: {}",
            if m.row.last_exit.is_empty() {
                "-"
            } else {
                &m.row.last_exit
            }
        )),
        Line::from(format!(
            "frames dropped {} · rejected {} · replayed {}",
            m.row.counters.dropped, m.row.counters.rejected, m.row.counters.replayed
        )),
        Line::from(format!(
            "calls {} · latency p50 {} p99 {}",
            m.calls,
            us(m.latency_p50_us),
            us(m.latency_p99_us)
        )),
        Line::from(format!("methods: {}", m.methods.join(", "))),
        Line::from(""),
        Line::from("Esc or Enter closes"),
    ];
    f.render_widget(Clear, popup);
    f.render_widget(
        Paragraph::new(text).block(Block::bordered().title(format!(" {} ", m.row.name))),
        popup,
    );
}

#[cfg(test)]
mod tests {
    use super::*;
    use modbot_ipc_schema::status::Row as StatusRow;

    fn m(addr: u8, name: &str, restarts: u32, p99: Option<f64>) -> Module {
        let mut m = Module::from_row(StatusRow {
            name: name.into(),
            addr,
            state: "running".into(),
            pid: 1,
            restarts,
            last_exit: String::new(),
            counters: Default::default(),
            heartbeat_age_ms: None,
            upgrades: 0,
        });
        m.latency_p99_us = p99;
        m
    }

    #[test]
    fn modules_sort_by_each_key_and_reverse_with_ties_by_address() {
        let mut v = vec![
            m(3, "b", 1, Some(5.0)),
            m(1, "c", 2, None),
            m(2, "a", 1, Some(9.0)),
        ];
        let names = |v: &[Module]| v.iter().map(|m| m.row.name.clone()).collect::<Vec<_>>();
        sort(&mut v, SortBy::Name, false);
        assert_eq!(names(&v), ["a", "b", "c"]);
        sort(&mut v, SortBy::Addr, false);
        assert_eq!(names(&v), ["c", "a", "b"]);
        sort(&mut v, SortBy::Restarts, true);
        assert_eq!(names(&v), ["c", "b", "a"]);
        sort(&mut v, SortBy::Latency, true);
        assert_eq!(names(&v), ["a", "b", "c"]);
    }
}
