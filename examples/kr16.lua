-- A KUKA KR 16 with a 16 kg load, simulated: the robot of DLR's MoRC experiment (elastic joints
-- on axes 1-3), behind the bus bridge in torque mode; its assemblies are in kr16/, and the
-- experiment is the robot program kr16_ff.lua:
--
--   modbot up examples/kr16.lua --lockstep &
--   modbot program run examples/kr16_ff.lua --domain kr16
--
-- The joints (link side: rad, N·m, kg·m²; the simulation's two-mass model, runtime/grid/src/bus/
-- plant.rs). Where the numbers come from:
-- - load and reach: KR 16-2 data sheet — 16 kg rated payload, 1611 mm reach, 235 kg robot,
--   156 °/s on axes 1-3 (2.7 rad/s).
-- - link inertia (axis 1: 60, axis 2: 50, axis 3: 18): the load at the reach the axis swings it
--   (16 kg at 1.5, 1.3 and 0.9 m: 36, 27, 13) plus the arm's own links (about 150 kg of the
--   235 kg move on axis 1, their centre of mass within 0.4 m: ~24; upper arm and forearm on
--   axis 2: ~23; forearm and wrist on axis 3: ~5).
-- - motor inertia at the link (24, 20, 8): a rotor of ~1e-3 kg·m² through a ratio of ~150
--   (J·n²: 20-25 for the large axes, less for axis 3): commonly 0.3-0.5 of the link's for
--   the main axes of an industrial arm.
-- - gear stiffness (1.0e5, 1.2e5, 6e4 N·m/rad): cycloid reducers of this size give 1e5-3e5
--   N·m/rad; chosen so the elastic modes fall at 12.2, 14.6 and 16.6 Hz (6.5, 7.8 and 9.2 Hz
--   with the motor held), the 10-20 Hz measured on robots of this class with load.
-- - gear damping (79, 79, 35 N·m·s/rad): 3 % of critical on each elastic mode.
-- - friction on the motor (viscous 80, 70, 30 N·m·s/rad; Coulomb 40, 40, 20 N·m): a few percent
--   of the rated torques (~1500, 1500, 600 N·m at the link).
-- - axes 4-6: the simulation's default joint (stiff, light).
-- The simulation has no gravity: the weight of axes 2 and 3 is left out of plant and
-- feed-forward alike (a constant torque a real controller compensates separately).

domain(vars.domain or "kr16")

-- `--var heartbeat_timeout=S`: how long a module may be silent before the supervisor judges it
-- hung (default 2 s).
supervision { heartbeat_timeout = tonumber(vars.heartbeat_timeout) or 2.0 }

grid { base_period = 0.001, priority = 60, assemblies = "kr16", assembly = "hold" }

component "robot" { type = "bus", host = "bus", period = 1,
                    params = { axes = 6, handover = true, watchdog = tonumber(vars.watchdog),
                               motor_inertia    = { 24, 20, 8, 0.5, 0.5, 0.5 },
                               link_inertia     = { 60, 50, 18, 2, 2, 2 },
                               stiffness        = { 1.0e5, 1.2e5, 6.0e4, 2e4, 2e4, 2e4 },
                               damping          = { 79, 79, 35, 10, 10, 10 },
                               viscous_friction = { 80, 70, 30, 1, 1, 1 },
                               coulomb_friction = { 40, 40, 20, 3, 3, 3 },
                               torque_limit     = { 3000, 3000, 1200, 200, 200, 200 },
                               -- `--var bus=ethercat --var interface=IF`: the drives are EtherCAT
                               -- slaves (see docs/ethercat.md); their torques are per mille of a
                               -- 100 Nm rated torque (10 units per Nm: up to 3276 Nm in 0x6071).
                               backend = vars.bus or "sim", interface = vars.interface,
                               torque_per_nm = 10, link_encoder = vars.bus == "ethercat" } }

-- The data recorder, on demand: a robot program records what the drives do between its
-- record { } and stop_record { } (examples/kr16_ff.lua records both feed-forward runs);
-- `modbot up --record FILE` records from the start.
record {
  signals = { "robot.link_position", "robot.demand_position", "robot.motor_position",
              "robot.motor_torque", "robot.state" },
  units = { ["robot.link_position"] = "rad", ["robot.demand_position"] = "rad",
            ["robot.motor_position"] = "rad", ["robot.motor_torque"] = "N m" },
  on_demand = true,
}
