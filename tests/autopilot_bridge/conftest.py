"""The shared test helpers of this room (bridge_pad, real_sitl) import by name from every
sub-folder, as they did when the tests were flat."""

import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
