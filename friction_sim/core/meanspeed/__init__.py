"""friction_sim.core.meanspeed.general."""
