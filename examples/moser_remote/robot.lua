-- MOSER split over two hosts: this is the robot's (examples/moser.lua without the control
-- station). Its bridge exports every module to the station's domain and imports the station's
-- control station, to which the high-level module and the intrusion module report.
--
--   robot host:    modbot up examples/moser_remote/robot.lua --var robot_ip=10.0.0.1
--   station host:  modbot up examples/moser_remote/station.lua --var robot_ip=10.0.0.1
--
-- Variables: domain (default moser_robot), station_domain (moser_station), robot_ip (the
-- address the robot's bridge listens on, 127.0.0.1), port (7447), speed (1).

local speed = tonumber(vars.speed or "1")
local sim = { MODBOT_SIM_SPEED = tostring(speed) }
local station = vars.station_domain or "moser_station"

domain(vars.domain or "moser_robot")

supervision { start_timeout = 20, heartbeat_timeout = 1.0, heartbeat_period = 0.1, stop_grace = 3 }

bridge {
  addr = 200,
  listen = { "tcp/" .. (vars.robot_ip or "127.0.0.1") .. ":" .. (vars.port or "7447") },
  exports = { "mobility", "collision_sonar", "nav_sonar", "near_ir", "intrusion", "high_level" },
  imports = { control_station = { addr = 20, domain = station } },
}
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

group "sensors" { "collision_sonar", "nav_sonar", "near_ir", "intrusion" }
