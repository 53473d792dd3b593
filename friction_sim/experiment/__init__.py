"""friction_sim.experiment: scenario files (:mod:`.scenario`), what an experiment is and yields (:mod:`.spec`),
step metrics (:mod:`.metrics`), the report (:mod:`.report`), the acceptance cases (:mod:`.acceptance`), and the
one ROS module here, the runner (:mod:`.runner`)."""
