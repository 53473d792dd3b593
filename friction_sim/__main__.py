"""``python -m friction_sim``: the same as the ``friction-sim`` command."""

from friction_sim.cli.main import main

raise SystemExit(main())
