"""The presentation layer: ipywidgets panels of both papers and the drawing helpers the figures use.

- :mod:`~repro.ui.panel`: what both panels share (guarded callbacks, batched updates).
- :mod:`~repro.ui.face_panel`: the blendshape panel of Lewis et al. 2005 (``BlendshapePanel``).
  its views in :mod:`~repro.ui.face_views`, its drag mode in :mod:`~repro.ui.drag_panel` (``DragPanel``).
- :mod:`~repro.ui.fighter_panel`: the kung-fu fighter panel of Pronost et al. (``FighterPanel``).
- :mod:`~repro.ui.render`: pyvista/matplotlib drawing (headless probe, face and skeleton images).
- :mod:`~repro.ui.webview`: a 3D view drawn in the browser (rotate, zoom) for both panels.
- :mod:`~repro.ui.tables`: DataFrames whose long column names may break, so tables fit the page.

Nothing in the library imports this package.
"""
