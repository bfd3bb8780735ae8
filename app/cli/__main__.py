"""``python -m app.cli``: the same as the ``voxelscope`` command."""

import sys

from . import main

sys.exit(main())
