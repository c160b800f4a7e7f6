"""``python -m nurbsmotion.cli``: the command, as ``python -m nurbsmotion`` runs it."""

import sys

from . import main

if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
