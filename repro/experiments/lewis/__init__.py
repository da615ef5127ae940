"""Lewis et al. 2005: one module per figure or measurement (Figs. 1-5, Section 5, Section 3).

common: the face models and drawing helpers the figures share.
"""
