-- A multi-rate time grid (MoRC's coordinator and logical execution time) across three host
-- processes: periods of 1, 2, 5 and 10 base ticks of 1 ms, with a chain A(1) → B(2) → C(5).
--
--   modbot up examples/grid_demo.lua --ticks 5000 --trace grid.trace   -- 5 s, every output traced
--   modbot top --domain grid_demo                                      -- the ledger, live

domain(vars.domain or "grid_demo")

supervision { heartbeat_timeout = 2.0 }

grid { base_period = 0.001, priority = 60 }   -- SCHED_FIFO where permitted (hosts get 59)

component "A" { type = "ramp",       host = "h1", period = 1,  params = { slope = 1 } }
component "B" { type = "gain",       host = "h2", period = 2,  params = { k = 2 } }
component "C" { type = "integrator", host = "h3", period = 5 }
component "D" { type = "sine",       host = "h1", period = 10, params = { amplitude = 1, freq = 5 } }
component "E" { type = "sum",        host = "h2", period = 1 }
component "F" { type = "delay",      host = "h3", period = 10 }
component "G" { type = "counter",    host = "h1", period = 2 }

connect "A.y -> B.u"
connect "B.y -> C.u"
connect "C.y -> E.a"
connect "D.y -> E.b"
connect "E.y -> F.u"
