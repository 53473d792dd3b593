"""friction_sim.core.runtime."""
