-- MOSER split over two hosts: this is the control station's (see robot.lua). Its bridge
-- connects to the robot's, imports the robot's modules under their own names — the station
-- calls high_level.patrol and reads mobility's blackboard as on one host — and exports the
-- control station, so that the robot's reports reach it.
--
-- Variables: domain (default moser_station), robot_domain (moser_robot), robot_ip
-- (127.0.0.1), port (7447), speed (1).

local speed = tonumber(vars.speed or "1")
local sim = { MODBOT_SIM_SPEED = tostring(speed) }
local robot = vars.robot_domain or "moser_robot"
local end_after_alert, max_duration = "5", "900"

domain(vars.domain or "moser_station")

supervision { start_timeout = 20, heartbeat_timeout = 1.0, heartbeat_period = 0.1, stop_grace = 3 }

local imports = {}
for name, addr in pairs({ mobility = 2, collision_sonar = 3, nav_sonar = 4, near_ir = 5,
                          intrusion = 6, high_level = 10 }) do
  imports[name] = { addr = addr, domain = robot }
end

bridge {
  addr = 200,
  connect = { "tcp/" .. (vars.robot_ip or "127.0.0.1") .. ":" .. (vars.port or "7447") },
  exports = { "control_station" },
  imports = imports,
}
module "control_station" {
  addr = 20, program = "modbot-control-station", env = sim,
  args = { "--patrol", "3", "--end-after-alert", end_after_alert, "--max-duration", max_duration },
  restart = { policy = "on-failure", give_up = "stop-system" },
}
