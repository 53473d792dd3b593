"""friction_sim.core.control.law."""
