"""friction_sim.core.physics."""
