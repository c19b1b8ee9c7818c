"""The simulated closed loop: the ECU controller, the loop at the SYNC rate, the harness, frequency responses, and the generic model of a rig."""
