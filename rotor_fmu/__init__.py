"""rotor_fmu: rotor models (Jeffcott, turbocharger beam, rotor files) and their FMUs.

Physics modules import no FMI; the PythonFMU slaves (jeffcott_rotor.py, turbocharger_rotor.py) wrap them.
"""
