"""friction_sim.core.engine."""
