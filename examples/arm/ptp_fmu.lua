-- Like ptp.lua, with the feed-forward an FMU: modbot_ff2.fmu (FMI 2.0 co-simulation, built from
-- C by the workspace's build: fmus/ff2/ff2.c), the inverse of the arm's elastic joints — a
-- two-mass model (motor, gear, link) with friction — instead of a rigid-body model. It runs in
-- a host process of its own (modbot-fmu-host); with the `fault` policy, a crash of it faults
-- the assembly and the drives stop.

local A = { 0.0, 0.0, 0.0, 0.0, 0.0, 0.0 }
local B = { 0.5, -0.4, 0.3, 0.6, -0.5, 0.8 }
local points = {}
for _, p in ipairs({ A, B }) do for _, x in ipairs(p) do points[#points + 1] = x end end

component "enable" { type = "drive_enable", host = "ctrl", period = 1, params = { axes = 6, mode = 8 } }
component "path"   { type = "waypoints",    host = "ctrl", period = 10,
                     params = { axes = 6, points = points, dwell = tonumber(vars.dwell or "0.2") } }
component "ptp"    { type = "ptp",          host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, handover = true, v_max = 1.0, a_max = 4.0 } }
-- The FMU's parameters are its model's (the plant's defaults: Jm = 0.5, Jl = 2, k = 2e4, ...);
-- its ports are its variables, q[1..6] read as q: f64[6].
component "ff"     { type = "fmu", fmu = "modbot_ff2.fmu", host = "ff", period = 1, policy = "fault",
                     params = { Tf = 0.005 } }
component "watch"  { type = "monitor",      host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, q_min = -3, q_max = 3, qd_max = 3,
                                following_max = tonumber(vars.following_max or "0.1") } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "ptp.done -> path.done"
connect "path.goal -> ptp.goal"
connect "robot.demand_position -> ptp.start"
connect "robot.handover -> ptp.handover"
connect "ptp.handover -> robot.handover"
connect "ptp.q -> robot.target_position"
connect "ptp.qd -> robot.target_velocity"
connect "ptp.q -> ff.q"
connect "ptp.qd -> ff.qd"
connect "ptp.qdd -> ff.qdd"
connect "ff.tau -> robot.target_torque"
connect "robot.link_position -> watch.q"
connect "robot.motor_velocity -> watch.qd"
connect "robot.demand_position -> watch.q_ref"
