"""Skip markers of the export tests that build C: the Cortex-M checks need the test extra's
ziglang and unicorn; a host build needs a C compiler (gcc, ``$CC``) or ziglang."""

from __future__ import annotations

import importlib.util

import pytest

from hpdob.testing import find_compiler

needs_zig = pytest.mark.skipif(
    importlib.util.find_spec("ziglang") is None or importlib.util.find_spec("unicorn") is None,
    reason="ziglang and unicorn (the test extra) are needed for the Cortex-M checks",
)
needs_host_cc = pytest.mark.skipif(
    find_compiler() is None and importlib.util.find_spec("ziglang") is None,
    reason="no host C compiler (gcc, $CC or ziglang)",
)
