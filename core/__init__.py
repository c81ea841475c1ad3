"""jampacked.core: the packing engine (load, approximate, place & grow, fill, certify)."""
