"""friction_sim.io: formats, files and sinks.  Messages and their bytes, the MCAP recorder and reader, CSV and
Parquet, parameter files, the live view; it runs no simulation (the engine and the runtimes are the experiment
layer's to drive: :mod:`friction_sim.experiment.verify`, :mod:`friction_sim.experiment.offline`)."""
