import sys
from pathlib import Path

import pytest

from inbetween_helpers import _strip

# `import core` from the repository root, as scripts and the extension do.
ROOT = str(Path(__file__).resolve().parents[2])
if ROOT not in sys.path:
    sys.path.insert(0, ROOT)


@pytest.fixture(scope="module")
def strip():
    return _strip()
