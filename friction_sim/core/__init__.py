"""friction_sim.core."""
