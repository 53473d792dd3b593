"""friction_sim.cli."""
