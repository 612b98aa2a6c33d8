"""Plumbing shared by the PythonFMU slaves of bearing_fmu and rotor_fmu (bundled into each FMU)."""
