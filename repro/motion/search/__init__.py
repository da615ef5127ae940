"""Motion retrieval (Sections 3.2.2-3.3): Kovar's aligned pose distance, k-means of poses, the
index, the paper's pruned search (Eq. 1) and the exact branch and bound with its compiled kernel."""
