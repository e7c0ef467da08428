-- A point-to-point move of the KR 16 with feed-forward, MoRC's chain: PTP (kinematic limits)
-- → Bessel low-pass → feed-forward → P-PI cascade on the motor side → drives in torque mode.
-- The feed-forward is `joint_ff` with the model the robot program gives in assembly data:
-- ptp_ff.model = "rigid" (the motor follows the link trajectory, torque for the whole
-- inertia) or "elastic" (the motor leads by the gear's deflection and its derivatives), with
-- the identified joint parameters (ptp_ff.motor_inertia, ...). So the program's two moves
-- are two assemblies from this file, loaded with their own parameters.
--
-- `settle` measures each move on the link side against the filtered reference three releases
-- old (the releases it takes through bessel, joint_ff, cascade and the bus): the peak
-- following error, the arrival (the trajectory's end), the residual oscillation after it and
-- the settling time into the band (ptp_ff.band).

local q = data("ptp_ff.q") or { 0, 0, 0, 0, 0, 0 }

component "enable"  { type = "drive_enable", host = "ctrl", period = 1, params = { axes = 6, mode = 10 } }
component "goal"    { type = "setpoint",     host = "ctrl", period = 1, params = { axes = 6, value = q } }
component "ptp"     { type = "ptp",          host = "ctrl", period = 1, policy = "fault",
                      params = { axes = 6, handover = true, v_max = data("ptp_ff.v") or 2.7,
                                 a_max = data("ptp_ff.a") or 4.0 } }
component "smooth"  { type = "bessel",       host = "ctrl", period = 1,
                      params = { axes = 6, bessel_hz = data("ptp_ff.bessel_hz") or 8 } }
component "ff"      { type = "joint_ff",     host = "ctrl", period = 1,
                      params = { axes = 6, model = data("ptp_ff.model") or "rigid",
                                 motor_inertia = data("ptp_ff.motor_inertia"),
                                 link_inertia = data("ptp_ff.link_inertia"),
                                 stiffness = data("ptp_ff.stiffness"), damping = data("ptp_ff.damping"),
                                 viscous = data("ptp_ff.viscous"), coulomb = data("ptp_ff.coulomb") } }
component "cascade" { type = "cascade",      host = "ctrl", period = 1,
                      params = { axes = 6, kp = 15, kv = { 5040, 4200, 1560, 150, 150, 150 },
                                 ki = { 37800, 31500, 11700, 1125, 1125, 1125 },
                                 tau_max = { 3000, 3000, 1200, 200, 200, 200 } } }
component "watch"   { type = "monitor",      host = "ctrl", period = 1, policy = "fault",
                      params = { axes = 6, q_min = -3, q_max = 3, qd_max = 3, following_max = 0.05 } }
component "settle"  { type = "settle",       host = "ctrl", period = 1,
                      params = { axes = 6, band = data("ptp_ff.band") or 1e-4, quiet = 0.2, lag = 3 } }

connect "robot.statusword -> enable.statusword"
connect "enable.controlword -> robot.controlword"
connect "enable.mode -> robot.mode"
connect "goal.value -> ptp.goal"
connect "robot.demand_position -> ptp.start"
connect "robot.handover -> ptp.handover"
connect "ptp.handover -> robot.handover"
connect "ptp.q -> smooth.q"
connect "ptp.qd -> smooth.qd"
connect "ptp.qdd -> smooth.qdd"
connect "smooth.q -> ff.q"
connect "smooth.qd -> ff.qd"
connect "smooth.qdd -> ff.qdd"
connect "ff.q_m -> cascade.q_ref"
connect "ff.qd_m -> cascade.qd_ref"
connect "ff.tau_ff -> cascade.tau_ff"
connect "robot.motor_position -> cascade.q"
connect "robot.motor_velocity -> cascade.qd"
connect "cascade.tau -> robot.target_torque"
connect "ff.q_m -> robot.target_position"
connect "ff.qd_m -> robot.target_velocity"
connect "robot.link_position -> watch.q"
connect "robot.motor_velocity -> watch.qd"
connect "robot.demand_position -> watch.q_ref"
connect "robot.link_position -> settle.q"
connect "smooth.q -> settle.q_ref"
connect "ptp.done -> settle.done"
