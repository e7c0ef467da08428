-- Your first grid component (examples/first_component): a sine clamped by `limiter`, a type
-- of your own that the program modbot-first-component makes and steps on host h_limit.
--
--   modbot up examples/first_component/limited.lua --ticks 1000 --trace limited.trace

domain(vars.domain or "first_component")
grid { base_period = 0.001 }

component_type "limiter" {
  program = "modbot-first-component",
  doc = "y = u clamped to ±limit; clamped = how often it clamped",
  inputs = { "u:f64" },
  outputs = { "y:f64", "clamped:i64" },
  params = { limit = 1.0 },
}

component "wave" { type = "sine", host = "h_wave", params = { amplitude = 2.0, freq = 5.0 } }
component "limit" { type = "limiter", host = "h_limit", params = { limit = 1.5 } }
connect "wave.y -> limit.u"
