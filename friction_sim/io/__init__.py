"""friction_sim.io."""
