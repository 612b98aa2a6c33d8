"""rotor_fmu."""
