"""Pronost et al. ~2008: one module per figure or measurement (Fig. 4 analog, Sections 3.3-3.4, Fig. 10 analog)."""
