-- A library of robot commands next to the program that requires it (require "tours"):
-- commands are written as the built-in ones are (runtime/program/src/library.lua).

command "tour" {
  doc = "the robot goes round between A and B (assembly ptp) for s seconds of grid time",
  params = { s = "seconds of grid time (required)" },
  pre = function(p)
    if not (type(p.s) == "number" and p.s > 0) then
      return false, "s is required: a positive number of seconds"
    end
  end,
  run = function(p)
    return { assembly = "ptp", timeout = p.s + 5 }
  end,
  done = function(p, r)
    return r.elapsed >= p.s   -- r.start_tick, r.tick, r.elapsed (s of grid time)
  end,
  eval = function(p, r)
    local q = read("robot.link_position")
    return { moved = math.abs(q[1]) + math.abs(q[2]), ticks = r.end_tick - r.start_tick }
  end,
}
