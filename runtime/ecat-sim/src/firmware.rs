//! The slave's firmware: how it reacts to the ESC's events. AL control requests run the state
//! machine (with the checks a slave stack makes before SAFE-OP), a full receive mailbox goes
//! to the mailbox server, and written outputs step the application.

use crate::al::{status_code, AlState};
use crate::esc::sync_manager::{SmDirection, SyncManager};
use crate::esc::EscEvent;
use crate::pdo;
use crate::process_data::{self, BoundLayout};
use crate::slave::{scratch_of, Slave};

const SM_MAILBOX_OUT: u8 = 0;
const SM_MAILBOX_IN: u8 = 1;
const SM_OUTPUTS: u8 = 2;
const SM_INPUTS: u8 = 3;

impl Slave {
    /// Writes AL status from the firmware's state and error indication.
    pub(crate) fn publish_al_status(&mut self, code: u16) {
        let status = u16::from(self.state.code()) | if self.error { 0x0010 } else { 0 };
        self.esc.set_al_status(status, code);
    }

    fn refuse(&mut self, code: u16) {
        tracing::debug!(slave = %self.config.name, state = ?self.state, code, "state change refused");
        self.error = true;
        self.publish_al_status(code);
    }

    /// Reacts to everything the ESC queued.
    pub(crate) fn handle_events(&mut self) {
        while let Some(event) = self.esc.next_event() {
            match event {
                EscEvent::AlControl(value) => self.on_al_control(value),
                EscEvent::MailboxReceived { sm } if sm == SM_MAILBOX_OUT => {
                    self.on_mailbox_request()
                }
                EscEvent::MailboxRead { sm } if sm == SM_MAILBOX_IN => self.flush_mailbox(),
                EscEvent::BufferWritten { sm } if sm == SM_OUTPUTS => {
                    self.last_outputs_ns = self.frame_ns;
                    self.step_if_running();
                }
                _ => {}
            }
        }
    }

    /// The sync manager watchdog: in OP, outputs must arrive within the watchdog time
    /// (0x0420 × (0x0400 + 2) × 40 ns, 100 ms by default) if SM2 enables its watchdog;
    /// otherwise the slave falls back to SAFE-OP with error 0x001B. Looked at when a frame
    /// arrives, which is when a master could see it.
    pub(crate) fn check_watchdog(&mut self) {
        if self.state != AlState::Op {
            return;
        }
        let sm = self.esc.sync_manager(SM_OUTPUTS);
        let Some(limit) = self.esc.sm_watchdog_ns() else {
            return;
        };
        if !sm.enabled() || !sm.watchdog_enabled() {
            return;
        }
        if self.frame_ns.saturating_sub(self.last_outputs_ns) > limit {
            tracing::debug!(slave = %self.config.name, "sync manager watchdog expired");
            self.go_down(AlState::SafeOp);
            self.esc.set_sm_watchdog_expired(true);
            self.refuse(status_code::SM_WATCHDOG);
        }
    }

    fn on_mailbox_request(&mut self) {
        let Some(request) = self.esc.mailbox_take(SM_MAILBOX_OUT) else {
            return;
        };
        if self.state == AlState::Init {
            return;
        }
        let send_size = usize::from(self.esc.sync_manager(SM_MAILBOX_IN).length);
        self.mailbox
            .on_request(&request, &mut self.od, self.state, send_size);
        self.flush_mailbox();
    }

    fn flush_mailbox(&mut self) {
        if let Some(reply) = self.mailbox.next_reply() {
            if !self.esc.mailbox_put(SM_MAILBOX_IN, &reply) {
                self.mailbox.unsend(reply);
            }
        }
    }

    /// One application cycle, if the process data runs and it has not stepped in this frame.
    pub(crate) fn step_if_running(&mut self) {
        if self.stepped_this_frame || !matches!(self.state, AlState::SafeOp | AlState::Op) {
            return;
        }
        self.stepped_this_frame = true;
        if self.state == AlState::Op && self.outputs.bytes() > 0 {
            let sm = self.esc.sync_manager(SM_OUTPUTS);
            let buffer = self.esc.pdi_read(sm.start, usize::from(sm.length));
            process_data::buffer_to_dictionary(&self.outputs, buffer, &mut self.od);
        }
        let dt_s = match self.esc.sync0_cycle_ns() {
            Some(ns) => f64::from(ns) * 1e-9,
            None => self.default_period_s,
        };
        self.app.step(&mut self.od, dt_s);
        self.steps += 1;
        self.write_inputs();
    }

    fn write_inputs(&mut self) {
        if self.inputs.bytes() == 0 {
            return;
        }
        let sm = self.esc.sync_manager(SM_INPUTS);
        let buffer = scratch_of(&mut self.scratch, usize::from(sm.length));
        process_data::dictionary_to_buffer(&self.inputs, &self.od, buffer);
        self.esc.pdi_write(sm.start, buffer);
    }

    fn on_al_control(&mut self, value: u16) {
        let acknowledge = value & 0x0010 != 0;
        if self.error && !acknowledge {
            // With the error indication set, only an acknowledged request is acted on.
            return;
        }
        if acknowledge {
            self.error = false;
        }
        let Some(target) = AlState::from_code((value & 0x000F) as u8) else {
            return self.refuse(status_code::UNKNOWN_STATE);
        };
        if target == AlState::Bootstrap {
            return self.refuse(status_code::BOOTSTRAP_NOT_SUPPORTED);
        }
        if target == self.state {
            return self.publish_al_status(status_code::NO_ERROR);
        }
        if self.state.is_down_to(target) {
            self.go_down(target);
            return self.publish_al_status(status_code::NO_ERROR);
        }
        if !self.state.is_next_step_up(target) {
            return self.refuse(status_code::INVALID_STATE_CHANGE);
        }
        let checked = match target {
            AlState::PreOp => self.check_mailbox(),
            AlState::SafeOp => self.start_process_data(),
            _ => Ok(()),
        };
        match checked {
            Ok(()) => {
                tracing::debug!(slave = %self.config.name, from = ?self.state, to = ?target, "AL state change");
                if target == AlState::Op {
                    // The watchdog counts from the request to OP.
                    self.last_outputs_ns = self.frame_ns;
                    self.esc.set_sm_watchdog_expired(false);
                }
                self.state = target;
                self.publish_al_status(status_code::NO_ERROR);
            }
            Err(code) => self.refuse(code),
        }
    }

    fn go_down(&mut self, target: AlState) {
        tracing::debug!(slave = %self.config.name, from = ?self.state, to = ?target, "AL state change");
        if self.state == AlState::Op {
            self.app.outputs_invalid(&mut self.od);
        }
        if target <= AlState::PreOp {
            self.esc.set_sm_deactivated(SM_OUTPUTS, true);
            self.esc.set_sm_deactivated(SM_INPUTS, true);
            self.outputs = BoundLayout::default();
            self.inputs = BoundLayout::default();
        }
        if target == AlState::Init {
            self.esc.set_sm_deactivated(SM_MAILBOX_OUT, true);
            self.esc.set_sm_deactivated(SM_MAILBOX_IN, true);
            self.mailbox.reset();
        }
        self.state = target;
    }

    fn check_mailbox(&mut self) -> Result<(), u16> {
        let layout = self.config.mailbox;
        let ok = |sm: SyncManager, start: u16, len: u16, direction: SmDirection| {
            sm.enabled()
                && sm.is_mailbox()
                && sm.start == start
                && sm.length == len
                && sm.direction() == direction
        };
        let out = self.esc.sync_manager(SM_MAILBOX_OUT);
        let inp = self.esc.sync_manager(SM_MAILBOX_IN);
        if !ok(
            out,
            layout.receive_offset,
            layout.receive_size,
            SmDirection::MasterWrites,
        ) || !ok(
            inp,
            layout.send_offset,
            layout.send_size,
            SmDirection::MasterReads,
        ) {
            return Err(status_code::INVALID_MAILBOX_CONFIG);
        }
        self.esc.set_sm_deactivated(SM_MAILBOX_OUT, false);
        self.esc.set_sm_deactivated(SM_MAILBOX_IN, false);
        Ok(())
    }

    fn check_buffer(&self, sm: u8, start: u16, bytes: usize, direction: SmDirection) -> bool {
        let config = self.esc.sync_manager(sm);
        if bytes == 0 {
            return !config.enabled();
        }
        let covered = (0..crate::esc::CHANNELS).any(|n| {
            let fmmu = self.esc.fmmu(n);
            let right_way = match direction {
                SmDirection::MasterWrites => fmmu.write,
                SmDirection::MasterReads => fmmu.read,
            };
            fmmu.enabled
                && right_way
                && fmmu.physical_start == start
                && usize::from(fmmu.length) >= bytes
        });
        config.enabled()
            && !config.is_mailbox()
            && config.start == start
            && usize::from(config.length) == bytes
            && config.direction() == direction
            && covered
    }

    fn start_process_data(&mut self) -> Result<(), u16> {
        let outputs = pdo::layout(&self.od, pdo::Direction::Rx)
            .map_err(|_| status_code::INVALID_OUTPUT_MAPPING)?;
        let inputs = pdo::layout(&self.od, pdo::Direction::Tx)
            .map_err(|_| status_code::INVALID_INPUT_MAPPING)?;
        if !self.check_buffer(
            SM_OUTPUTS,
            self.config.outputs_start,
            outputs.bytes(),
            SmDirection::MasterWrites,
        ) {
            return Err(status_code::INVALID_OUTPUT_CONFIG);
        }
        if !self.check_buffer(
            SM_INPUTS,
            self.config.inputs_start,
            inputs.bytes(),
            SmDirection::MasterReads,
        ) {
            return Err(status_code::INVALID_INPUT_CONFIG);
        }
        let activation = self.esc.sync_activation();
        if activation & 0x02 != 0 {
            match self.esc.sync0_cycle_ns() {
                None => return Err(status_code::INVALID_DC_SYNC_CONFIG),
                Some(cycle) if cycle < self.config.min_sync0_cycle_ns => {
                    return Err(status_code::DC_INVALID_CYCLE_TIME)
                }
                Some(_) => {}
            }
        }
        self.outputs = BoundLayout::bind(outputs, &self.od);
        self.inputs = BoundLayout::bind(inputs, &self.od);
        self.esc.set_sm_deactivated(SM_OUTPUTS, false);
        self.esc.set_sm_deactivated(SM_INPUTS, false);
        // Valid inputs from the first cycle on.
        self.write_inputs();
        Ok(())
    }
}
