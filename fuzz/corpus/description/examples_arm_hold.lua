-- Holds the robot where it is commanded to be, in cyclic synchronous position mode. It also
-- recovers from a safe stop: drive_enable resets faults and leaves quick stop (disable
-- voltage, then enable), once the bus bridge obeys an assembly again.

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
