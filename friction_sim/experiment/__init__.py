"""friction_sim.experiment: where the simulation meets files and nodes.  Scenario files (:mod:`.scenario`), what an
experiment is and yields (:mod:`.job`), step metrics (:mod:`.metrics`), the report (:mod:`.report`), the acceptance
cases (:mod:`.acceptance`), the re-simulation of a recording (:mod:`.verify`: ``replay --verify``, calibration's
fit), a recording made without ROS (:mod:`.offline`), and the one ROS module here, the runner (:mod:`.runner`)."""
