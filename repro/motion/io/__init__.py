"""Reading and writing motion files (Section 3.2: clips "stored in the BVH standard format"):
BVH, and the Acclaim ASF/AMC originals of the CMU database."""
