"""``python -m caveflow_ray STUDY ...``: see :mod:`caveflow_ray.driver`."""

import sys

from .driver import main

sys.exit(main())
