"""friction_sim.core.model."""
