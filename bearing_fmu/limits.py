"""The accepted ranges of the journal bearing's parameters (no FMI, no numba import).

One table for the physics (``bearing_fmu.model.BearingParams`` checks it) and the FMU
(``bearing_fmu.journal_bearing`` declares it as the variables' min/max in modelDescription.xml, which
the scenario loader checks with the scenario's line).

Physical values: wide enough for any real machine (a micro turbine's 0.1 mm radius to a hydro
generator's guide bearing of 4 m bore; gases to cold gear oil), narrow enough to refuse a value in
the wrong unit: R or B in mm (R: 25 for 25 mm was a 25 m journal), eta0 in mPa s (12 for 0.012),
sigma_rough in um; a pressure in bar is not caught (1 Pa is a valid pressure). eta0 goes down to
1e-7 Pa s: below any gas, but the film then fails with its own message (docs/fmus.md).
"""

from __future__ import annotations

MAX_N_PHI, MAX_N_Z = 8192, 2048
MAX_FILM_CELLS = 2**18       # n_phi * n_z (262 144 cells; 1536 x 40 is 61 440)
# psi = C/R: journal bearings have 0.3 to 3 per mille; 1e-4 .. 0.1 refuses a value in per mille
# (1.5 for 1.5e-3) and a clearance in metres (1.5e-5 for 15 um), both of which passed as psi > 0
# before 2026-12-06 (the first with a film 100 x too thin).
PSI_MIN, PSI_MAX = 1.0e-4, 0.1
R_RANGE, B_RANGE, ETA0_RANGE = (1.0e-4, 2.0), (1.0e-4, 4.0), (1.0e-7, 10.0)
PRESSURE_MAX, SIGMA_ROUGH_MAX = 1.0e8, 1.0e-4
CONTACT_KE_MAX, MU_CONTACT_MAX = 1.0e12, 10.0
