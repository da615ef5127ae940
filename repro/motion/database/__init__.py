"""The annotated motion database (Section 3.2): clips and their hits, the database's file, the real
sources (CMU, Bandai Namco), augmentation, and the synthetic database a fresh clone runs on."""
