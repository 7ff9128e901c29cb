"""``python -m deformesh_cli``: the same command as ``deformesh``."""

from .cli import main

main()
