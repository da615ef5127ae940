"""Tables that fit the page (repro.ui.tables)."""

from __future__ import annotations

import pandas as pd


def test_header_breaks_only_in_header_cells():
    from repro.ui.tables import header_breaks

    df = pd.DataFrame({"rotation_change_max_deg": [1.5], "clip": ["actor2_punch_left_high"]})
    out = header_breaks(df._repr_html_())
    assert "rotation_<wbr>change_<wbr>max_<wbr>deg" in out
    assert "<td>actor2_punch_left_high</td>" in out  # values untouched
    assert out.replace("<wbr>", "") == df._repr_html_()


def test_wrap_table_headers_registers_the_html_formatter():
    from IPython.core.interactiveshell import InteractiveShell

    from repro.ui.tables import wrap_table_headers

    shell = InteractiveShell.instance()
    assert wrap_table_headers(shell)
    df = pd.DataFrame({"a_b": [1]})
    data, _ = shell.display_formatter.format(df)
    assert "a_<wbr>b" in data["text/html"] and data["text/plain"] == repr(df)
