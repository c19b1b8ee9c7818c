"""Set-point profiles: the `Profile` type, the named maneuvers, the seeded flight and the diagnosis excitation."""
