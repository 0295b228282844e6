"""``python -m rdea_lab.cli``: the ``rdea-lab`` command."""

from . import entry

entry()
