-- A 6-axis simulated robot arm (MoRC): the bus bridge serves six CiA 402 drives on two-mass
-- elastic joints every 1 ms tick; the `hold` control structure enables the drives in cyclic
-- synchronous position mode and holds where the robot stands.
--
--   modbot up examples/arm.lua
--   modbot bus --domain arm      -- cycles, missed cycles, each drive's state and mode
--   modbot top --domain arm      -- the grid's ledger
--
-- Swapping to a `ptp` assembly at runtime (`modbot assembly switch`) is the next step of this
-- example; the controllers it uses (`ptp`, `feedforward`, `cascade`, `monitor`) exist already.

domain(vars.domain or "arm")

supervision { heartbeat_timeout = 2.0 }

grid { base_period = 0.001, priority = 60 }

-- The bus: served every tick, owns the drives (the host named "bus" is the bus bridge).
component "robot"  { type = "bus",           host = "bus",  period = 1, params = { axes = 6 } }
-- The hold assembly.
component "enable" { type = "drive_enable",  host = "ctrl", period = 1, params = { axes = 6, mode = 8 } }
component "hold"   { type = "hold_position", host = "ctrl", period = 1, params = { axes = 6 } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "robot.motor_position -> hold.start"
connect "hold.q -> robot.target_position"
connect "hold.qd -> robot.target_velocity"   -- zeros: no velocity feed-forward while holding
connect "hold.qdd -> robot.target_torque"    -- zeros: no torque feed-forward while holding
