"""Retargeting (Section 3.4.1): the morphology-independent representation of Kulpa et al. 2005
on the same joint tree, its extension across joint trees, and one dispatcher between them."""
