-- MOSER, the MRA paper's mobile security robot (NOSC, 1990), in a simulated office building.
--
-- The control station sends the robot to patrol wing 3. The high-level module plans paths on
-- its map of rooms and wings and drives the mobility base; the collision-avoidance sonar stops
-- the base before anything in its way (the planner then goes around it), the navigation sonar
-- sees all around, the near-infrared ring can stand in for the collision sonar, and the
-- intrusion module fuses heat, light and motion into an alert for the operator. The scenario
-- ends a few simulated seconds after the alert with a summary.
--
--   modbot up examples/moser.lua                  -- real time
--   modbot up examples/moser.lua --var speed=10   -- ten times faster
--   modbot up examples/moser.lua --var domain=x   -- in another domain (the tests use their own)
--   modbot up examples/moser.lua --var endless=1  -- patrols until stopped: no end, no summary

local speed = tonumber(vars.speed or "1")
local sim = { MODBOT_SIM_SPEED = tostring(speed) }
-- When the control station ends the scenario (simulated seconds): after the alert, at the latest.
local end_after_alert, max_duration = "5", "900"
if vars.endless then
  end_after_alert, max_duration = "inf", "inf"
end

domain(vars.domain or "moser")

supervision { start_timeout = 20, heartbeat_timeout = 1.0, heartbeat_period = 0.1, stop_grace = 3 }

-- Started in this order; stopped in reverse. The control station comes last: it starts the patrol.
module "mobility" {
  addr = 2, program = "modbot-mobility", env = sim,
  args = { "--world", "moser", "--sonar", "collision_sonar", "--speed", "0.5" },
}
module "collision_sonar" {
  addr = 3, program = "modbot-sonar", env = sim,
  args = { "--world", "moser", "--sensors", "12", "--arc", "180", "--max-range", "10" },
}
module "nav_sonar" {
  addr = 4, program = "modbot-sonar", env = sim,
  args = { "--world", "moser", "--sensors", "24", "--arc", "360", "--max-range", "10",
           "--period-ms", "50" },
}
module "near_ir" {
  addr = 5, program = "modbot-sonar", env = sim,
  args = { "--world", "moser", "--kind", "ir", "--sensors", "11", "--arc", "180",
           "--max-range", "0.9" },
}
module "intrusion" {
  addr = 6, program = "modbot-intrusion", env = sim, args = { "--threshold", "0.8" },
}
module "high_level" {
  addr = 10, program = "modbot-high-level", env = sim,
}
module "control_station" {
  addr = 20, program = "modbot-control-station", env = sim,
  args = { "--patrol", "3", "--end-after-alert", end_after_alert, "--max-duration", max_duration },
  restart = { policy = "on-failure", give_up = "stop-system" },
}

group "sensors" { "collision_sonar", "nav_sonar", "near_ir", "intrusion" }
