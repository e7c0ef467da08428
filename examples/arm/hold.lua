-- Holds the robot where it is commanded to be, in cyclic synchronous position mode. A safe
-- stop or a drive fault is not ended by switching here: `modbot robot reset` brings the drives
-- back (the bus bridge enables them, and this assembly holds where they are).

component "enable" { type = "drive_enable",  host = "ctrl", period = 1,
                     params = { axes = 6, mode = 8, reset_faults = true } }
component "hold"   { type = "hold_position", host = "ctrl", period = 1, params = { axes = 6, handover = true } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "robot.demand_position -> hold.start"   -- bumpless: where the drives were commanded
connect "robot.handover -> hold.handover"       -- and the command it replaces, exactly
connect "hold.handover -> robot.handover"       -- what a successor takes over from
connect "hold.q -> robot.target_position"
connect "hold.qd -> robot.target_velocity"
connect "hold.qdd -> robot.target_torque"
