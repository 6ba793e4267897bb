"""``python -m tactile_learn.cli`` (and ``torchrun ... -m tactile_learn.cli train ...``): the CLI."""

import sys

from tactile_learn.cli import main

sys.exit(main())
