"""friction_sim.experiment."""
