"""``python -m rankgame``: the same entry point as the ``rankgame`` command."""

from rankgame.cli import main

raise SystemExit(main())
