-- A sensor fleet at the MRA's full address space: `n` sensor modules (default 253 less the
-- aggregators) report a temperature every second to `aggregators` aggregator modules
-- (default 4). Every address 1..=254 is used: the aggregators, the sensors and the
-- supervisor. Try `modbot up examples/fleet.lua`, then in another terminal `modbot ls`,
-- `modbot call agg1.summary` (tools reach a full system through the supervisor), or
-- `modbot up examples/fleet.lua --var n=16` for a small one.

domain(vars.domain or "fleet")

local aggregators = tonumber(vars.aggregators or "4")
local n = tonumber(vars.n or tostring(253 - aggregators))
if aggregators < 1 or n < 1 or n + aggregators > 253 then
  error("fleet: 1 <= aggregators, 1 <= n and n + aggregators <= 253 (one address is the supervisor's)")
end

-- Hundreds of modules: a heartbeat a second is enough to see a hung one within five.
supervision { heartbeat_period = 1, heartbeat_timeout = 5, start_timeout = 60 }

for a = 1, aggregators do
  module("agg" .. a) {
    addr = a,
    program = "modbot-fleet",
    args = { "aggregator" },
    restart = "always",
  }
end

for i = 1, n do
  module("sensor" .. i) {
    addr = aggregators + i,
    program = "modbot-fleet",
    args = { "sensor", "--aggregator", "agg" .. ((i - 1) % aggregators + 1) },
    restart = "always",
  }
end
