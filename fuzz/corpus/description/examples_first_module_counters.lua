-- Two of your first module (examples/first_module): `b` counts what others add; `a` adds 1
-- to `b` every second and keeps b's answer.
--
--   modbot up examples/first_module/counters.lua
--   modbot bb b total --domain counters          -- grows by 1 a second
--   modbot call b.add 10 --domain counters       -- answers the new total

domain(vars.domain or "counters")

module "b" { addr = 11, program = "modbot-first-module" }
module "a" { addr = 10, program = "modbot-first-module", args = { "--peer", "b" } }
