-- Holds the KR 16 where it is commanded to be, in cyclic synchronous torque mode: the
-- position held goes through the P-PI cascade on the motor side (gains for a 60 rad/s
-- velocity loop on each joint's whole inertia). After a safe stop: `modbot robot reset`.

component "enable"  { type = "drive_enable",  host = "ctrl", period = 1,
                      params = { axes = 6, mode = 10, reset_faults = true } }
component "hold"    { type = "hold_position", host = "ctrl", period = 1, params = { axes = 6, handover = true } }
component "cascade" { type = "cascade",       host = "ctrl", period = 1,
                      params = { axes = 6, kp = 15, kv = { 5040, 4200, 1560, 150, 150, 150 },
                                 ki = { 37800, 31500, 11700, 1125, 1125, 1125 },
                                 tau_max = { 3000, 3000, 1200, 200, 200, 200 } } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "robot.demand_position -> hold.start"
connect "robot.handover -> hold.handover"
connect "hold.handover -> robot.handover"
connect "hold.q -> cascade.q_ref"
connect "hold.qd -> cascade.qd_ref"
connect "hold.qdd -> cascade.tau_ff"      -- zeros: at rest
connect "robot.motor_position -> cascade.q"
connect "robot.motor_velocity -> cascade.qd"
connect "cascade.tau -> robot.target_torque"
connect "hold.q -> robot.target_position"
connect "hold.qd -> robot.target_velocity"
