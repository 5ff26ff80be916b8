"""rh5_hyrodyn_mapper."""
