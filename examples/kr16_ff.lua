-- MoRC's experiment as one robot program: the KR 16 (examples/kr16.lua, 16 kg load) makes the
-- same Bessel-filtered 5° point-to-point move on axes 1-3 once with a rigid-body feed-forward
-- and once with an elastic (structural-elastic inverse) feed-forward — each its own assembly,
-- prepared and switched to by its command, without a restart — and compares the residual
-- oscillation of the links after arrival. Both moves start from rest at the same point.
--
--   modbot up examples/kr16.lua --lockstep --gate 1000 &   -- every digit the same every run
--   modbot program run examples/kr16_ff.lua --domain kr16
--   modbot data ls --domain kr16                       -- both runs and their results
--
-- It records the whole experiment (the drives: link, demand and motor positions, motor torque)
-- to kr16_ff.h5 in the directory it runs in, and plots both residuals after arrival next to it
-- (kr16_ff.svg).

-- The joint model the feed-forward uses (identified; here: the simulation's, see kr16.lua).
local model = {
  motor_inertia = { 24, 20, 8, 0.5, 0.5, 0.5 }, link_inertia = { 60, 50, 18, 2, 2, 2 },
  stiffness = { 1.0e5, 1.2e5, 6.0e4, 2e4, 2e4, 2e4 }, damping = { 79, 79, 35, 10, 10, 10 },
  viscous = { 80, 70, 30, 1, 1, 1 }, coulomb = { 40, 40, 20, 3, 3, 3 },
}
local deg = math.pi / 180
local home = { 0, 0, 0, 0, 0, 0 }
local away = { 5 * deg, 5 * deg, 5 * deg, 0, 0, 0 }
-- The reach each axis swings the load at (m): a link angle there is that many metres per rad.
local reach = 1.6

command "move" {
  doc = "a 5° class move with the feed-forward ff (rigid or elastic), until the links settle",
  params = { ff = "rigid or elastic", q = "the goal, rad per axis" },
  pre = function(p)
    if p.ff ~= "rigid" and p.ff ~= "elastic" then
      return false, ("ff must be \"rigid\" or \"elastic\", not %s"):format(tostring(p.ff))
    end
    if type(p.q) ~= "table" or #p.q ~= 6 then
      return false, "q must be the goal of the six axes"
    end
  end,
  run = function(p)
    local args = { model = p.ff, q = p.q, v = 2.7, a = 4.0, bessel_hz = 8, band = 1e-4 }
    for name, values in pairs(model) do args[name] = values end
    return { assembly = "ptp_ff", args = args, timeout = 30 }
  end,
  done = function(p, r)
    return read("settle.settled")
  end,
  eval = function(p, r)
    -- A move is "ok" only where the links arrived: nothing claims a motion that did not occur.
    local q = read("robot.link_position")
    for axis = 1, 6 do
      if math.abs(q[axis] - p.q[axis]) > 1e-3 then
        return false, ("the links did not arrive: axis %d is at %.5f rad, the goal %.5f rad")
          :format(axis, q[axis], p.q[axis])
      end
    end
    local arrival = read("settle.arrival_tick")
    return {
      residual = read("settle.residual"),
      settling_s = read("settle.settling_s"),
      peak_following = read("settle.peak_following"),
      arrival_tick = arrival,
      end_tick = r.end_tick,
      move_s = (arrival - r.start_tick) / 1000,
    }
  end,
}

-- Each move starts from rest at home: the links' last oscillation has 2 s to die away.
record { file = "kr16_ff.h5" }
move { ff = "elastic", q = home }
wait { s = 2 }
local rigid = move { ff = "rigid", q = away }
move { ff = "rigid", q = home }
wait { s = 2 }
local elastic = move { ff = "elastic", q = away }
move { ff = "elastic", q = home }
local recording = stop_record {}
hold {}

local function show(name, r)
  print(("%-8s residual after arrival %.3f mrad (%.2f mm at %.1f m), settling %.3f s into 0.1 mrad, peak following %.2f mrad")
    :format(name, r.residual * 1e3, r.residual * reach * 1e3, reach, r.settling_s, r.peak_following * 1e3))
end
show("rigid", rigid)
show("elastic", elastic)
-- The residuals over time, from the recording: how far the links of axes 1-3 are from the goal
-- (the largest of the three), from arrival until the links had settled.
local function residual(r)
  local rows = recorded(recording.file, "robot.link_position", r.arrival_tick, r.end_tick)
  local x, y = {}, {}
  for i, q in ipairs(rows.values) do
    local worst = 0
    for axis = 1, 3 do worst = math.max(worst, math.abs(q[axis] - away[axis])) end
    x[i] = (rows.ticks[i] - r.arrival_tick) / 1000
    y[i] = worst * 1e3
  end
  return x, y
end
local rx, ry = residual(rigid)
local ex, ey = residual(elastic)
local svg = plot {
  file = recording.file:sub(1, -4) .. ".svg",
  title = "KR 16, 5° move on axes 1-3: residual link oscillation after arrival",
  x = "time after arrival (s)", y = "largest link deviation from the goal, axes 1-3 (mrad)",
  lines = { { name = "rigid feed-forward", x = rx, y = ry },
            { name = "elastic feed-forward", x = ex, y = ey } },
}
print(("recorded %d rows to %s; residuals plotted in %s"):format(recording.rows, recording.file, svg))
local ratio = rigid.residual / elastic.residual
data("kr16.ratio", ratio)
print(("ratio rigid/elastic %.1f"):format(ratio))
if not (ratio >= 6) then -- a NaN (no residual in either run) is no six-fold cut either
  error(("the elastic feed-forward cuts the residual oscillation by %.1f, not 6 or more"):format(ratio))
end
