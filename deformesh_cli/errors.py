"""Exceptions raised by the deformesh core.

Every failure a user can act on is a :class:`DeformeshError` whose message is
one line naming the file, the problem and where.  The command-line layer turns
them into exit codes: :class:`OptionError` is a usage error (exit 2), every
other subclass a processing failure (exit 1).
"""


class DeformeshError(Exception):
    """Base class of every error the core raises on purpose."""


class InputError(DeformeshError):
    """The contour or state file cannot be used (unreadable, malformed, invalid)."""


class OptionError(DeformeshError):
    """An option value is inconsistent with the input (for example a box that misses it)."""


class LimitError(DeformeshError):
    """The work would exceed a stated limit (grid nodes, memory)."""


class SelectionError(DeformeshError):
    """No simple grid path could be fitted to the contour."""


class FoldError(DeformeshError):
    """The deformation could not proceed without folding a triangle."""


class ContractError(DeformeshError):
    """A mesh does not meet the mesh contract (see README, 'The contract')."""
