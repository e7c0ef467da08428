-- A robot program for the arm (examples/arm.lua): three commands, three assemblies.
--
--   modbot up examples/arm.lua &
--   modbot program run examples/programs/three.lua --domain arm
--   modbot data ls --domain arm

require "tours"                               -- tours.lua, next to this file

ptp { q = { 0.2, -0.1, 0.1, 0, 0, 0 } }       -- assembly goto, until it has settled
tour { s = 0.3 }                              -- assembly ptp, round and round for 0.3 s
hold {}                                       -- assembly hold
print(("peak following error of the ptp: %.3g rad"):format(data("ptp.peak_following")))
