"""sphinx-gallery image scraper for bfemp's figures.

bfemp draws on ``matplotlib.figure.Figure`` objects with an Agg canvas and never touches pyplot
(``bfemp.plotting``), so sphinx-gallery's default scraper, which asks pyplot for its open
figures, sees none. This one collects every ``Figure`` an example's code block left in the
example's globals (a name bound to a figure, or a list or dict of them) that it has not shown
yet, in the order they were bound, and writes each to the gallery's next image path.
"""

from __future__ import annotations

from matplotlib.figure import Figure
from sphinx_gallery.scrapers import figure_rst

_SHOWN: dict[str, set[int]] = {}


def _figures(value: object) -> list[Figure]:
    if isinstance(value, Figure):
        return [value]
    if isinstance(value, list | tuple):
        return [v for v in value if isinstance(v, Figure)]
    if isinstance(value, dict):
        return [v for v in value.values() if isinstance(v, Figure)]
    return []


def figure_scraper(block: object, block_vars: dict, gallery_conf: dict) -> str:
    """Save the figures new in this code block; return their reST (sphinx-gallery's protocol)."""
    shown = _SHOWN.setdefault(str(block_vars["src_file"]), set())
    paths = []
    for value in list(block_vars["example_globals"].values()):
        for fig in _figures(value):
            if id(fig) in shown:
                continue
            shown.add(id(fig))
            path = next(block_vars["image_path_iterator"])
            fig.savefig(path, dpi=90)
            paths.append(path)
    return figure_rst(paths, gallery_conf["src_dir"])
