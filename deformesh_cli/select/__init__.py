"""Stage 1: the background grid, the grid nodes the contour points take, and the path.

- :mod:`.uniform`: Appendix A's Cartesian grid of one step, the node selection,
  the grid path and its forced diagonals, the fallbacks (shifted grids, halved
  steps);
- :mod:`.trace`: a simple grid path traced around a region of cells, where
  Appendix A's choice gives none;
- :mod:`.graded`: a graded background (a balanced quadtree of square cells
  split into right isosceles triangles, conforming across levels);
- :mod:`.construct`: the graded grid laid for the contour's sizes and thin parts,
  and each ring's loop of grid edges fitted to its points.
"""

from .uniform import (
    DEFAULT_MARGIN_CELLS,
    DEFAULT_MAX_NODES,
    DIAG_BACKSLASH,
    DIAG_SLASH,
    EVEN_SPACING_RATIO,
    GRIDS,
    MAX_NODES_CEILING,
    Grid,
    NoFreeNode,
    Selection,
    build_path,
    check_path,
    choose_grid,
    estimate_nodes,
    fit_path,
    force_diagonals,
    grid_triangles,
    select,
    select_nodes,
)

__all__ = [
    "DEFAULT_MARGIN_CELLS",
    "DEFAULT_MAX_NODES",
    "MAX_NODES_CEILING",
    "DIAG_BACKSLASH",
    "DIAG_SLASH",
    "EVEN_SPACING_RATIO",
    "GRIDS",
    "Grid",
    "NoFreeNode",
    "Selection",
    "build_path",
    "check_path",
    "choose_grid",
    "estimate_nodes",
    "fit_path",
    "force_diagonals",
    "grid_triangles",
    "select",
    "select_nodes",
]
