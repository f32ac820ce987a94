"""The collision engine: one collision of any scene, its drivers (lockstep, lanes, Pallas),
tangents, devices and input checks."""
