-- The MRA demo system (NOSC MODBOT, 1990): the mobility base drives toward an obstacle and the
-- sonar stops it at two feet. Check it with `modbot check examples/mra_demo.lua`.

domain "mra_demo"

-- Started in this order, stopped in reverse.
module "sonar" {
  addr = 2,
  program = "modbot-sonar",
  args = { "--obstacle", "3,0" },
  restart = "on-failure",
}

module "mobility" {
  addr = 3,
  program = "modbot-mobility",
  restart = "on-failure",
}
