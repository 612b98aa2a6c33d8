"""Coupling defect of interface-Jacobian forces on a constant macro step (``summary.json`` ``coupling_defect``).

With interface-Jacobian coupling (docs/stiff-coupling.md) the rotor integrates over a macro step
[T, T + H] the force ``F_used(t) = P(t) - K (r(t) - r(T)) - C (v(t) - v(T))`` (P the order-k
prediction, K, C the film coefficients it received at T, r, v its own journal position and
velocity). The film then computes the force at the rotor's new state, F(T + H). The defect

    d = F(T + H) - F_used(T + H) = F(T + H) - P(T + H) + K dr + C dv

is what the rotor did not integrate: the explicit predictor/corrector indicator of Busch &
Schweizer (PAMM 10, 2010) with the interface-Jacobian correction (Meyer, Kraft & Schweizer,
J. Comput. Nonlinear Dyn. 16 (2021) 041002); :mod:`.signal_scales` uses the same quantity to
control the error-controlled step. On a constant step nothing used to look at it, so a phase in
which the film force and the force the rotor integrated part company was silent: the
mass-conserving films' contact phase from rest (film-force spikes of 2.6 kN on a 29 N load at
the shipped 0.1 ms step) and the turbocharger's rub regime (docs/runups.md).

This monitor computes d after every accepted constant step for every force that the rotor
receives extrapolated with its coefficients, per journal (the x and y components of station i
together: ``|d| = hypot(d_x, d_y)``), and keeps |d| and |F| per step (bounded: past
``MAX_KEPT`` steps, neighbouring pairs are merged, the larger |d| kept). At the end it reports,
per journal, the typical force (the median |F| over the run), the largest |d| and when, and the
steps whose |d| exceeded ``coupling.defect_limit`` (default ``LIMIT``) times the typical force,
merged into episodes (flagged steps at most ``EPISODE_GAP`` steps apart; the ``MAX_EPISODES``
with the largest |d| are listed, in time order; ``rotorcosim plot`` marks them in
``eccentricity.png``). Such a step means the rotor integrated a force that differed from the
film's by more than the limit times the film's typical force.

A large defect is a reason to look, not a proof that the result depends on the step. Measured
(docs/coupling.md, "Coupling defect"): in the shipped free-to-air run-up's whirl a film that has
run empty refills within one step, its force jumping from 0 to 80 N; the defect of that step
(61 N) is the same at half the step (68 N), and so is the jump (Fx 79 and 82 N). In the from-rest contact
phase the largest defects are 2.6-6.0 kN at 0.1 ms, 6.5-7.4 kN at 50 us and 0.1-0.4 kN at
10 us: there the film forces depend on the step. Which of the two a flagged episode is, only a
run with a smaller ``coupling.macro_step`` tells. The warning says so.

``coupling.defect_retries: N`` (default 0) acts on it: a macro step whose defect is over the limit
is redone from the saved states in halves (:class:`.step_control.DiscardHalving`, the machinery of
``discard_retries``), each half judged again, down to H / 2^N; a piece still over the limit there is
accepted and counted (``retries.unresolved_steps``). During the run the limit is taken against a
running typical force (the median |F| of the last ``RECENT`` accepted macro steps; before the first,
|F| at the start), as the run's median is not known yet; the report keeps the run's median, so a step
accepted during the run may still count in ``steps_over``. The pieces of a redone macro step make one
row (the largest |d| of its pieces), so ``steps`` stays the number of macro steps. The criterion is
the value |d| of each piece, not its impulse |d| h: the force error the rotor integrates over the
macro step then stays within the same bound as over an unredone step. A jump within a step (the
film refilling in the whirl) keeps its defect at any step and is never resolved; the turbocharger's
rub regime is (docs/coupling.md, "Redoing the steps over the limit").

Not monitored: the error-controlled step (it has its own estimate and rejects such steps; with
``step_control.until`` the constant steps after ``until`` are monitored, ``monitored_from`` says so,
and the error-controlled ones count in ``steps_not_monitored``), the
iterative scheme (it iterates the force to its tolerance), forces the rotor receives interpolated
(Gauss-Seidel with the bearing stepping first), macro steps redone in halves after an
fmi2Discard (the rotor integrated each half with fresh coefficients; with ``defect_retries`` they are
monitored piece by piece) and the start-up steps of
extrapolation order k >= 2 (the first k - 1, iterated from saved states); these are counted in
``steps_not_monitored``.

Under Jacobi the film computes F(T + H) at the kinematics it was fed, their prediction, not
where the rotor went; the coefficients the film returns move it there,
``F(T + H) - K (r - r_fed) - C (v - v_fed)`` (the film's own K, C at T + H), so Jacobi's one-step
lag counts in d. On a linear film d is then the recorded force's change over the step (tests);
on the Jeffcott run-up's first 20 ms (half-Sommerfeld) the median d over the typical force was
1.0-1.9x the true error against the monolithic reference (docs/coupling.md).
"""

from __future__ import annotations

import math
from array import array

import numpy as np

from orchestrator.coupling.signal_scales import FORCE_RE, jacobian_groups
from orchestrator.coupling.signals import lagrange_weights
from orchestrator.names import match

LIMIT = 1.0            # default of coupling.defect_limit: a step is flagged when |d| > limit x the typical force
EPISODE_GAP = 10       # flagged steps at most this many steps apart form one episode
MAX_EPISODES = 100     # episodes listed per journal in summary.json (the largest |d|, in time order)
MAX_KEPT = 1 << 20     # steps kept per journal before neighbouring pairs are merged
RECENT = 1024          # accepted steps whose median |F| is the running typical force (coupling.defect_retries)
TYPICAL_EVERY = 64     # steps between two updates of the running typical force


class DefectMonitor:
    """The coupling defect of a constant-step run (module docstring).

    ``names``: the history's columns (``consumer.input``), ``extrapolated``: those the
    consumer receives extrapolated, ``connections``: the scenario's. :meth:`before` is called
    before a macro step, :meth:`after` once it is accepted.
    """

    def __init__(self, names: list[str], extrapolated, connections, *, k: int, unit_of=None, limit: float = LIMIT,
                 macro_step: float | None = None, signals: tuple[str, ...] = ()):
        ext = set(extrapolated)
        groups = [(j, terms) for j, terms in jacobian_groups(names, connections) if names[j] in ext]
        journals: dict[str, list] = {}
        for j, terms in groups:
            inst, _, var = names[j].rpartition(".")
            a, i = FORCE_RE.match(var).groups()          # jacobian_groups matched it so
            journals.setdefault(f"{inst}.F_{i}", []).append((a, j, terms))
        # coupling.defect_signals: more inputs, each its own entry with the plain prediction error
        # (no linearisation); the interface-Jacobian forces and their coefficients are covered above
        # (a pattern that matches only those counts as matched: they are monitored already)
        taken = {j for j, _ in groups} | {kc for _, terms in groups for kc, _, _ in terms}
        ext_cols = [(n, j) for j, n in enumerate(names) if n in ext]
        self.unmatched = []               # patterns that match no extrapolated coupling input
        for pat in signals:
            hits = set(match(pat, [n for n, _ in ext_cols]))
            if not hits:
                self.unmatched.append(pat)
            for n, j in ext_cols:
                if n in hits and j not in taken and n not in journals:
                    journals[n] = [("", j, [])]
        self.journals = list(journals)
        self.k = int(k)
        self.limit = float(limit)         # coupling.defect_limit
        self.macro_step = macro_step      # coupling.macro_step, for the rerun the warning suggests
        # the force's unit (``unit_of(column)``: the consumer input's declared unit, or None) per journal
        self.units = {name: (unit_of(names[v[0][1]]) if unit_of else None) or "" for name, v in journals.items()}
        # per journal, x before y: ((force column, ((coefficient column, kinematics column, 1 / gain),
        # four per force; none for a defect_signals entry)), ...); the per-step arithmetic is on
        # Python floats (a few us a step, where numpy on these short rows took 25-47 us in a run)
        self._plan = [tuple((j, tuple(terms)) for _, j, terms in sorted(v)) for v in journals.values()]
        self._force_list = [j for forces in self._plan for j, _ in forces]
        # the kinematics the bearing receives extrapolated (Jacobi; under Gauss-Seidel with the rotor
        # first they are interpolated, the rotor's new values): the film's F(T+H) was computed at their
        # prediction, not at where the rotor went; the coefficients it returned carry the difference
        self._kin_ext = sorted({uc for forces in self._plan for _, terms in forces for _, uc, _ in terms
                                if names[uc] in ext})
        self._pred_cols = np.array(self._force_list + self._kin_ext, dtype=np.intp)
        self._pkin: dict[int, float] = {}
        self._row_d = [0.0] * len(journals)
        self._row_f = [0.0] * len(journals)
        self._weights: dict[tuple, np.ndarray] = {}
        self._pred: list[float] = []
        self._prev: list[float] | None = None
        self._t = array("d")    # per kept row: the step's end time, |d| and |F| per journal (float32)
        self._d = array("f")
        self._f = array("f")
        self._n = 0             # rows kept
        self._stride = 1        # steps per kept row (doubles when MAX_KEPT is reached)
        self._acc_d: list = []             # the pending row when stride > 1: max |d|, |F| of its first step
        self._acc_f: list = []
        self._acc_t = 0.0
        self._acc_n = 0
        self.steps = 0          # steps monitored
        # the running typical force per journal for coupling.defect_retries: the median |F| of the last
        # RECENT accepted steps (recomputed every TYPICAL_EVERY steps; before the first, |F| at the start)
        # coupling.defect_retries, set by the step controller that redoes steps on their defect (> 0: the
        # running typical force is kept and measure() judges)
        self.halvings = 0
        self.retried_steps = 0            # macro steps redone in halves for their defect
        self.unresolved_steps = 0         # of those: a piece at H / 2^halvings still over the limit
        self._recent = np.zeros((RECENT, len(self.journals)))
        self._n_recent = 0
        self._typical: list[float] | None = None
        self._piece_d: list[float] | None = None     # the pieces of a macro step redone in halves, merged
        self.skipped = 0        # steps not monitored: redone in halves after a discard, or k >= 2 start-up

    def __bool__(self) -> bool:
        return bool(self.journals)

    # ----------------------------------------------------------------- per step
    def before(self, history, t: float, t_next: float) -> None:
        """Keep the prediction P(t_next) of the forces and the values at t (history before the step)."""
        p = min(self.k, history.count - 1)
        self._prev = prev = history.store[1].tolist()        # Python floats: ~20 numpy calls less per step
        nf = len(self._force_list)
        if p <= 0:
            pred = [prev[j] for j in self._force_list + self._kin_ext]
        else:
            nodes = tuple(np.round((history.times[1:p + 2] - t) / (t_next - t), 12))
            w = self._weights.get(nodes)
            if w is None:
                w = self._weights[nodes] = lagrange_weights(nodes, [1.0])[0]
            pred = (w @ history.store[1:p + 2, self._pred_cols]).tolist()
        self._pred = pred[:nf]
        if self._kin_ext:
            self._pkin = dict(zip(self._kin_ext, pred[nf:]))

    def after(self, history, t_next: float, *, skip: bool = False) -> None:
        """The defect of the step just accepted (history's newest level ``t_next``)."""
        if self._prev is None:
            return
        if skip:
            self.skipped += 1
            self._prev = None
            return
        self.measure(history)
        self.accept(t_next)

    def measure(self, history) -> float:
        """The defect of the step just done (history's newest level), into the pending row; returns the
        largest ``|d| / (limit x typical)`` over the journals with ``halvings`` > 0 (the typical force the
        running one: the median |F| of the last ``RECENT`` accepted steps; before the first, |F| at the
        step's start; a journal whose typical force is 0 is not judged), else 0.0. :meth:`accept` keeps the
        row, :meth:`drop` forgets it (the step is redone)."""
        new, prev, pkin = history.store[1].tolist(), self._prev, self._pkin
        row_d, row_f = self._row_d, self._row_f
        m = 0
        for g, forces in enumerate(self._plan):
            d2 = f2 = 0.0
            for j, terms in forces:
                s = 0.0
                for kc, uc, inv_gain in terms:
                    s += prev[kc] * (new[uc] - prev[uc]) * inv_gain      # what the rotor subtracted
                    fed = pkin.get(uc)
                    if fed is not None:           # the film's force moved to where the rotor went
                        s -= new[kc] * (new[uc] - fed) * inv_gain
                f = new[j]
                d = f - self._pred[m] + s
                d2 += d * d
                f2 += f * f
                m += 1
            row_d[g], row_f[g] = math.sqrt(d2), math.sqrt(f2)
        worst = 0.0
        if not self.halvings:
            return worst
        typ = self._typical
        if typ is None:              # no step kept yet: the force at the step's start
            typ = self._typical = [math.sqrt(sum(prev[j] ** 2 for j, _ in forces)) for forces in self._plan]
        for g, d in enumerate(row_d):
            if typ[g] > 0.0:
                worst = max(worst, d / (self.limit * typ[g]))
        return worst

    def accept(self, t_next: float, *, piece: bool = False) -> None:
        """Keep the row :meth:`measure` computed (the step ending at ``t_next`` is accepted). ``piece``: it is
        a piece of a macro step redone in halves; the pieces are merged (the largest |d|, |F| at the
        end) into one row by :meth:`commit` at the macro step's end, so that every row is one macro step."""
        self._prev = None
        if piece:
            if self._piece_d is None:
                self._piece_d = list(self._row_d)
            else:
                self._piece_d = [max(x, y) for x, y in zip(self._piece_d, self._row_d)]
            return
        self._commit_row(t_next, self._row_d, self._row_f)

    def commit(self, t_next: float) -> None:
        """Keep the merged row of a macro step redone in pieces (:meth:`accept` with ``piece``)."""
        if self._piece_d is not None:
            d, self._piece_d = self._piece_d, None
            self._commit_row(t_next, d, self._row_f)

    def _commit_row(self, t_next: float, row_d, row_f) -> None:
        self.steps += 1
        if self.halvings:
            recent = self._recent
            recent[self._n_recent % RECENT] = row_f
            self._n_recent += 1
            if self._n_recent <= TYPICAL_EVERY or self._n_recent % TYPICAL_EVERY == 0:
                self._typical = np.median(recent[:min(self._n_recent, RECENT)], axis=0).tolist()
        self._keep(t_next, row_d, row_f)

    def drop(self) -> None:
        """Forget the row :meth:`measure` computed (the step is redone in halves)."""
        self._prev = None

    def _keep(self, t: float, d, f) -> None:
        """Keep one step's |d| and |F| per journal (``d``, ``f``: sequences), or merge it into the pending
        row when ``_stride`` > 1 (the larger |d| and its time, |F| of the row's first step)."""
        if self._stride > 1:
            if self._acc_n == 0:
                self._acc_d, self._acc_f, self._acc_t = list(d), list(f), t
            else:
                if max(d) > max(self._acc_d):
                    self._acc_t = t
                self._acc_d = [max(a, b) for a, b in zip(self._acc_d, d)]
            self._acc_n += 1
            if self._acc_n < self._stride:
                return
            d, f, t = self._acc_d, self._acc_f, self._acc_t
            self._acc_n = 0
        self._t.append(t)
        self._d.extend(d)
        self._f.extend(f)
        self._n += 1
        if self._n >= MAX_KEPT:
            self._halve()

    def _halve(self) -> None:
        """Merge neighbouring kept rows (the larger |d| and its time; |F| of the first)."""
        t, d, f = self._arrays()
        m = len(t) // 2
        t2, d2, f2 = t[:2 * m].reshape(m, 2), d[:2 * m].reshape(m, 2, -1), f[:2 * m:2]
        second = d2[:, 1].max(axis=1) > d2[:, 0].max(axis=1)
        t_new = np.where(second, t2[:, 1], t2[:, 0])
        d_new = d2.max(axis=1)
        self._t, self._d, self._f = array("d", t_new.tolist()), array("f", d_new.ravel().tolist()), \
            array("f", f2.ravel().tolist())
        self._n = m
        self._stride *= 2

    def _arrays(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        k = len(self.journals)
        return (np.frombuffer(self._t, dtype=np.float64).copy(),
                np.frombuffer(self._d, dtype=np.float32).reshape(-1, k).copy(),
                np.frombuffer(self._f, dtype=np.float32).reshape(-1, k).copy())

    # ------------------------------------------------------------------- report
    def statistics(self) -> dict:
        """``summary.json`` ``coupling_defect`` (module docstring)."""
        t, d, f = self._arrays()
        out = {"limit": self.limit, "steps": self.steps, "steps_not_monitored": self.skipped,
               "steps_per_row": self._stride, "journals": {}}
        if self.halvings:
            out["retries"] = {"halvings": self.halvings, "retried_steps": self.retried_steps,
                              "unresolved_steps": self.unresolved_steps}
        for g, name in enumerate(self.journals):
            dj, fj = d[:, g].astype(float), f[:, g].astype(float)
            if not len(t):
                out["journals"][name] = {"typical": None, "max_defect": None, "t_max_defect": None,
                                         "steps_over": 0, "episodes": []}
                continue
            typical = float(np.median(fj))
            i = int(np.argmax(dj))
            over = np.flatnonzero(dj > self.limit * typical) if typical > 0 else np.zeros(0, dtype=np.intp)
            episodes = []
            if over.size:
                cuts = np.flatnonzero(np.diff(over) > EPISODE_GAP) + 1
                for idx in np.split(over, cuts):
                    k = idx[np.argmax(dj[idx])]
                    episodes.append({"t_start": _time(t[idx[0]]), "t_end": _time(t[idx[-1]]),
                                     "steps": int(idx.size) * self._stride, "max_defect": float(dj[k]),
                                     "t_max_defect": _time(t[k])})
            out["journals"][name] = {
                "unit": self.units.get(name, ""), "typical": typical, "max_defect": float(dj[i]),
                "t_max_defect": _time(t[i]),
                "median_defect": float(np.median(dj)),
                "steps_over": int(over.size) * self._stride, "episode_count": len(episodes),
                "first_flagged": _time(t[over[0]]) if over.size else None,
                "last_flagged": _time(t[over[-1]]) if over.size else None,
                "episodes": sorted(sorted(episodes, key=lambda e: -e["max_defect"])[:MAX_EPISODES],
                                   key=lambda e: e["t_start"])}
        return out

    def note(self, statistics: dict | None = None) -> str | None:
        """The warning when some step's defect exceeded the limit, or None."""
        st = statistics or self.statistics()
        hits = [(name, j) for name, j in st["journals"].items() if j.get("steps_over")]
        r = st.get("retries")
        redone = ""
        if r and r["retried_steps"]:
            redone = (f"coupling.defect_retries redid {r['retried_steps']} macro step(s) in halves down to "
                      f"macro_step / 2^{r['halvings']}, judged against the typical force of the last "
                      f"{RECENT} steps; {r['unresolved_steps']} still had a piece over the limit there (a jump "
                      "within a step, such as a film refilling, is never resolved; a phase that keeps needing the "
                      "smallest step wants coupling.step_control: {type: error}). ")
        if not hits:
            return None
        parts = []
        for name, j in hits:
            u = f" {j['unit']}" if j.get("unit") else ""
            first, last = j["first_flagged"], j["last_flagged"]
            parts.append(f"{name}: {j['steps_over']} steps in {j['episode_count']} episode"
                         f"{'s' if j['episode_count'] != 1 else ''} between t={first:.6g} and {last:.6g} s, "
                         f"largest {j['max_defect']:.4g}{u} against a typical size of {j['typical']:.4g}{u} "
                         f"(t={j['t_max_defect']:.6g} s)")
        last = max(j["last_flagged"] for _, j in hits)
        h = self.macro_step
        rerun = (f"rerun up to there with half the step (--set coupling.macro_step={h / 2:.6g} --set "
                 f"stop_time={_time(last + 20 * h):.6g})" if h else "rerun that interval with half the "
                 "coupling.macro_step")
        return ("coupling defect: in some macro steps the value a coupling signal took at the step's end differed "
                "from what its consumer integrated over the step (the prediction, for a force with interface-Jacobian "
                f"coefficients also their linearisation) by more than {self.limit:g}x the signal's typical size "
                "(coupling.defect_limit): "
                + "; ".join(parts) + ". The results at those times may depend on the macro step (a contact "
                f"phase or rub does; a film that refills within one step does not): {rerun}, or use "
                "coupling.step_control: {type: error}, and compare (summary.json coupling_defect; docs/coupling.md, "
                "'Coupling defect')" + (". " + redone.rstrip() if redone else ""))


def relative_defects(cd) -> list[tuple[str, dict, float, float | None]]:
    """``[(name, entry, max_defect / typical, median_defect / typical or None), ...]`` of a summary's
    ``coupling_defect`` (``cd``), for the entries whose typical (> 0) and max_defect are finite
    numbers; what ``rotorcosim run`` prints and ``compare`` tabulates (a summary read back may come
    from anyone)."""
    def number(x) -> bool:
        return isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x)

    journals = cd.get("journals") if isinstance(cd, dict) else None
    out = []
    for name, j in (journals.items() if isinstance(journals, dict) else ()):
        if not isinstance(j, dict):
            continue
        f, d, m = j.get("typical"), j.get("max_defect"), j.get("median_defect")
        if number(f) and number(d) and f > 0:
            out.append((name, j, d / f, m / f if number(m) else None))
    return out


def _time(t) -> float:
    """A step's end time without the last bits of ``t0 + n * h`` (0.0116, not 0.011600000000000001)."""
    return float(f"{float(t):.12g}")
