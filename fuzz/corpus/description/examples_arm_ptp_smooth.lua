-- Like ptp.lua with a smoother motion: the trajectory passes a 2nd-order Bessel low-pass
-- filter and the limits are lower. Swapped with ptp, it shows a change of control structure
-- while the robot moves.

local A = { 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 }
local B = { 0.5, -0.4, 0.3, 0.6, -0.5, 0.8 }
local points = {}
for _, p in ipairs({ B, A }) do for _, x in ipairs(p) do points[#points + 1] = x end end

component "enable" { type = "drive_enable", host = "ctrl", period = 1, params = { axes = 6, mode = 8 } }
component "path"   { type = "waypoints",    host = "ctrl", period = 10,
                     params = { axes = 6, points = points, dwell = tonumber(vars.dwell or "0.2") } }
component "ptp"    { type = "ptp",          host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, handover = true, v_max = 0.8, a_max = 3.0, bessel_hz = 8 } }
component "ff"     { type = "feedforward",  host = "ctrl", period = 1,
                     params = { axes = 6, inertia = { 2.0, 2.0, 1.0, 0.2, 0.2, 0.1 } } }
component "watch"  { type = "monitor",      host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, q_min = -3, q_max = 3, qd_max = 3,
                                following_max = tonumber(vars.following_max or "0.1") } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "ptp.done -> path.done"
connect "path.goal -> ptp.goal"
connect "robot.demand_position -> ptp.start"
connect "robot.handover -> ptp.handover"    -- and the command it replaces, exactly
connect "ptp.handover -> robot.handover"    -- what a successor takes over from
connect "ptp.q -> robot.target_position"
connect "ptp.qd -> robot.target_velocity"
connect "ptp.q -> ff.q"
connect "ptp.qd -> ff.qd"
connect "ptp.qdd -> ff.qdd"
connect "ff.tau_ff -> robot.target_torque"
connect "robot.link_position -> watch.q"
connect "robot.motor_velocity -> watch.qd"
connect "robot.demand_position -> watch.q_ref"
