"""generated/ is current, module by module: the bundled serial arms' modules (share
3 of 3, so that pytest-xdist's loadfile spreads the renders), each rendered alone and
compared with its checked-in files (tests/helpers.py compare_or_update_generated;
`pytest --update-generated` rewrites)."""

from __future__ import annotations

import pytest
from helpers import compare_or_update_generated, generated_share, update_generated


@pytest.mark.parametrize("stem", generated_share(2, 3))
def test_module_is_current(stem, request):
    compare_or_update_generated(stem, update_generated(request.config))
