"""bearing_fmu."""
