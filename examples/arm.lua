-- A 6-axis simulated robot arm (MoRC): the bus bridge serves six CiA 402 drives on two-mass
-- elastic joints every 1 ms tick; the control structure is an assembly, swapped at runtime.
--
--   modbot up examples/arm.lua                     -- starts with the `hold` assembly
--   modbot assembly switch ptp --domain arm        -- the robot moves between A and B
--   modbot assembly switch hold --domain arm       -- and holds where it is commanded to be
--   modbot bus --domain arm                        -- cycles, missed cycles, drive states
--   modbot top --domain arm                        -- the grid's ledger
--   modbot up examples/arm.lua --record arm.h5     -- records the bus (below) to HDF5
--   python3 examples/plot_recording.py arm.h5     -- link position and following error
--   modbot up examples/arm.lua --var bridge=tcp/10.0.0.1:7447   -- watched from another host
--
-- The assemblies are the files in examples/arm/: hold.lua, ptp.lua (trajectory generator,
-- rigid-body feed-forward, monitor) and ptp_smooth.lua (the same with a Bessel filter and a
-- P-PI cascade in torque mode).

domain(vars.domain or "arm")

supervision { heartbeat_timeout = 2.0 }

grid { base_period = 0.001, priority = 60, assemblies = "arm", assembly = vars.assembly or "hold" }

-- The bus: served every tick, owns the drives (the host named "bus" is the bus bridge). It
-- stays when the assembly changes; the assemblies connect to its ports.
-- With `handover`, the running trajectory generator tells it the command it will give two ticks
-- on, which it forwards to the generator of an assembly taking over (bumpless in velocity).
-- `--var watchdog=N`: base periods without a tick before the bus judges the coordinator lost and
-- quick-stops the drives (default 3); more on a host that steals milliseconds at a time.
--
-- `--var bus=ethercat --var interface=IF`: the drives are EtherCAT slaves on the network interface
-- IF (real CiA 402 drives, or `modbot-ecat-sim` on the other end of a veth pair: see
-- docs/ethercat.md), each with a load-side encoder for the link's position; `--var vendor=V
-- --var product=P`: the identity every drive must have (checked at start); `--var dc=true`:
-- distributed clocks, SYNC0 every base period.
component "robot" { type = "bus", host = "bus", period = 1,
                    params = { axes = 6, handover = true, watchdog = tonumber(vars.watchdog),
                               backend = vars.bus or "sim", interface = vars.interface,
                               vendor = tonumber(vars.vendor), product = tonumber(vars.product),
                               link_encoder = vars.bus == "ethercat", dc = vars.dc == "true" } }

-- The data recorder: what the drives do, tick by tick, written to HDF5 off the real-time path
-- by a process of its own. It runs when `modbot up --record FILE` names the file.
record {
  signals = { "robot.link_position", "robot.demand_position", "robot.motor_position",
              "robot.motor_velocity", "robot.motor_torque", "robot.statusword", "robot.state" },
  units = { ["robot.link_position"] = "rad", ["robot.demand_position"] = "rad",
            ["robot.motor_position"] = "rad", ["robot.motor_velocity"] = "rad/s",
            ["robot.motor_torque"] = "N m" },
}

-- `--var bridge=ENDPOINT`: a Zenoh bridge listening there exports the grid's ledger and the
-- robot's state, so that `modbot top` in another host's domain that imports `coordinator` and
-- `host_bus` shows this grid and robot (docs/remote.md). It reads; it commands nothing.
if vars.bridge then
  bridge { addr = 200, listen = { vars.bridge },
           exports = { coordinator = { "ledger", "status" }, host_bus = { "robot", "bus" } } }
end
