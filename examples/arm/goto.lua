-- Moves the robot to one goal and holds it there: the assembly of a robot program's `ptp`
-- command (`modbot program`). Its parameters are in assembly data, where the command put them
-- before it switched here (MoRC: assembly parameters come from the Assembly Data database):
-- goto.q (the goal, rad), goto.v and goto.a (velocity and acceleration limits), and
-- goto.bessel_hz (a Bessel low-pass on the trajectory, 0: none). Without them (modbot check)
-- it goes home at 1 rad/s.
--
-- A synchronized point-to-point trajectory with rigid-body feed-forward, watched by a monitor
-- whose breach faults the assembly; `settle` measures the motion (peak following error,
-- arrival, residual oscillation, settling time) and says when it is settled: the command
-- waits for settle.settled and records the rest.

local q = data("goto.q") or { 0, 0, 0, 0, 0, 0 }
local v = data("goto.v") or 1.0
local a = data("goto.a") or 4.0
local bessel = data("goto.bessel_hz") or 0
local band = data("goto.band") or 1e-3

component "enable" { type = "drive_enable", host = "ctrl", period = 1, params = { axes = 6, mode = 8 } }
component "goal"   { type = "setpoint",     host = "ctrl", period = 1, params = { axes = 6, value = q } }
component "ptp"    { type = "ptp",          host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, handover = true, v_max = v, a_max = a, bessel_hz = bessel } }
component "ff"     { type = "feedforward",  host = "ctrl", period = 1,
                     params = { axes = 6, inertia = { 2.0, 2.0, 1.0, 0.2, 0.2, 0.1 } } }
component "watch"  { type = "monitor",      host = "ctrl", period = 1, policy = "fault",
                     params = { axes = 6, q_min = -3, q_max = 3, qd_max = 3,
                                following_max = tonumber(vars.following_max or "0.1") } }
component "settle" { type = "settle",       host = "ctrl", period = 1, params = { axes = 6, band = band } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "goal.value -> ptp.goal"
connect "robot.demand_position -> ptp.start"    -- bumpless: starts where the drives were commanded
connect "robot.handover -> ptp.handover"        -- and the command it replaces, exactly
connect "ptp.handover -> robot.handover"        -- what a successor takes over from
connect "ptp.q -> robot.target_position"
connect "ptp.qd -> robot.target_velocity"
connect "ptp.q -> ff.q"
connect "ptp.qd -> ff.qd"
connect "ptp.qdd -> ff.qdd"
connect "ff.tau_ff -> robot.target_torque"
connect "robot.link_position -> watch.q"        -- the "laser tracker": what the arm really does
connect "robot.motor_velocity -> watch.qd"
connect "robot.demand_position -> watch.q_ref"
connect "robot.link_position -> settle.q"
connect "robot.demand_position -> settle.q_ref"
connect "ptp.done -> settle.done"
