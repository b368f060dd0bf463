"""Path classification: the streaming observer (numba) and the labeller."""
