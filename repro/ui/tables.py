"""Tables that fit the notebook page: long column names may break after an underscore.

pandas writes ``rotation_change_max_deg`` as one unbreakable word, so a table of such
columns is as wide as its headers (notebook 04's 24 columns: 2,740 px, at 1,250 px of
window the tables of six notebooks overflow at the right).  :func:`header_breaks` adds a
``<wbr>`` (an optional line break, invisible otherwise) after each ``_`` in the header
cells; :func:`wrap_table_headers` makes it the HTML of every DataFrame shown in an IPython
session.  Only the HTML changes: the text (``text/plain``) of a table is pandas' own.
"""

from __future__ import annotations

import re

__all__ = ["header_breaks", "wrap_table_headers"]

_TH = re.compile(r"(<th\b[^>]*>)([^<]*)(</th>)")


def header_breaks(html: str) -> str:
    """``html`` with ``_<wbr>`` for each ``_`` in the text of its ``<th>`` cells."""
    return _TH.sub(lambda m: m[1] + m[2].replace("_", "_<wbr>") + m[3], html)


def wrap_table_headers(shell=None) -> bool:
    """Show DataFrames in this IPython session with breakable headers; False outside IPython."""
    if shell is None:
        from IPython import get_ipython

        shell = get_ipython()
    if shell is None:
        return False
    import pandas as pd

    def html(df):
        out = df._repr_html_()
        return None if out is None else header_breaks(out)

    shell.display_formatter.formatters["text/html"].for_type(pd.DataFrame, html)
    return True
