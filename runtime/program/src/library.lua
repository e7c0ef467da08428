-- The command library every robot program starts with: MoRC's robot commands as skills, each
-- a precondition (pre), an execution (run: an assembly and its parameters, then done: when it
-- has finished) and an evaluation (eval: the results kept in assembly data). A program's own
-- commands are written the same way, in Lua libraries next to it (require "name").
--
-- They drive the arm of examples/arm.lua: its bus component is `robot`, and its assemblies
-- `goto` (a point-to-point motion measured by a `settle` component) and `hold`.

local function axes()
  return #read("robot.link_position")
end

local function positive(p, name)
  local x = p[name]
  if x ~= nil and not (type(x) == "number" and x > 0 and x < math.huge) then
    return false, ("%s must be a positive number, not %s"):format(name, tostring(x))
  end
  return true
end

command "ptp" {
  doc = "moves to q on a synchronized point-to-point trajectory and waits until it has settled",
  params = {
    q = "the goal: one joint position per axis, rad (required)",
    v = "velocity limit, rad/s (default 1)",
    a = "acceleration limit, rad/s² (default 4)",
    bessel_hz = "Bessel low-pass of the trajectory, Hz (default 0: none)",
    band = "settled when the following error stays within this, rad (default 0.001)",
    timeout = "give up after this many seconds of grid time (default 60)",
  },
  pre = function(p)
    if type(p.q) ~= "table" then
      return false, "q is required: the goal, one joint position per axis (q = { ... })"
    end
    local n = axes()
    if #p.q ~= n then
      return false, ("q has %d values; the robot has %d axes"):format(#p.q, n)
    end
    for i, x in ipairs(p.q) do
      if type(x) ~= "number" or x ~= x or math.abs(x) == math.huge then
        return false, ("q[%d] is %s, not a finite number"):format(i, tostring(x))
      end
    end
    for _, name in ipairs({ "v", "a", "band", "timeout" }) do
      local ok, why = positive(p, name)
      if not ok then return false, why end
    end
    return true
  end,
  run = function(p)
    return {
      assembly = "goto",
      args = { q = p.q, v = p.v or 1.0, a = p.a or 4.0, bessel_hz = p.bessel_hz or 0.0,
               band = p.band or 1e-3 },
      timeout = p.timeout or 60,
    }
  end,
  done = function(p, r)
    return read("settle.settled")
  end,
  eval = function(p, r)
    return {
      peak_following = read("settle.peak_following"),
      residual = read("settle.residual"),
      settling_s = read("settle.settling_s"),
      arrival_tick = read("settle.arrival_tick"),
    }
  end,
}

command "hold" {
  doc = "holds the robot where it is commanded to be",
  params = {},
  run = function(p)
    return { assembly = "hold" }
  end,
}

command "reset" {
  doc = "acknowledges a safe stop or a drive fault and brings the robot back, holding where it is (as `modbot robot reset`); refused while the cause persists",
  params = {},
  run = function(p)
    p.done = robot_reset()
  end,
  eval = function(p, r)
    return { done = p.done }
  end,
}

command "wait" {
  doc = "waits s seconds of grid time; the running assembly goes on",
  params = { s = "seconds of grid time (required)" },
  pre = function(p)
    if not (type(p.s) == "number" and p.s >= 0 and p.s < math.huge) then
      return false, ("s must be a number of seconds ≥ 0, not %s"):format(tostring(p.s))
    end
    return true
  end,
  run = function(p)
    return { timeout = p.s + 1 }
  end,
  done = function(p, r)
    return r.elapsed >= p.s
  end,
}

-- Recordings: the system's recorder (record { signals = { ... }, on_demand = true } in its
-- description, on host `record` unless it says) writes from record { } to stop_record { }.
local function recorder(p)
  return (p.recorder or "host_record")
end

command "record" {
  doc = "records signals of the system (its recorder's) to an HDF5 file, from now until stop_record",
  params = {
    file = "the HDF5 file (required; relative: to the directory the program runs in)",
    signals = "the signals to record, { \"comp.port\", ... } (default: every one the recorder has)",
    recorder = "the recorder's host module (default host_record)",
  },
  pre = function(p)
    if type(p.file) ~= "string" or p.file == "" then
      return false, "file is required: the HDF5 file to write (file = \"run.h5\")"
    end
    if p.signals ~= nil and type(p.signals) ~= "table" then
      return false, "signals must be a table of \"comp.port\" names"
    end
    for i, s in ipairs(p.signals or {}) do
      if type(s) ~= "string" then
        return false, ("signals[%d] is %s, not a \"comp.port\" name"):format(i, tostring(s))
      end
    end
    return true
  end,
  run = function(p)
    p.written = call(recorder(p) .. ".start", absolute(p.file), table.unpack(p.signals or {}))
  end,
  eval = function(p, r)
    return { file = p.written, start_tick = r.start_tick }
  end,
}

command "stop_record" {
  doc = "ends the recording record { } started; results: its file and rows",
  params = { recorder = "the recorder's host module (default host_record)" },
  run = function(p)
    p.file, p.rows = call(recorder(p) .. ".stop")
  end,
  eval = function(p, r)
    return { file = p.file, rows = p.rows }
  end,
}
