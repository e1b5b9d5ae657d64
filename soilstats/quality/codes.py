"""The data-quality codes: what each means, why it matters, what to do (one home).

``docs/quality.md`` repeats this wording (a test checks every code is there). ``excluded``
says whether the samples a code names are left out of every fit in the default mode
(``quality="clean"``); the other codes only flag.  ``nature`` says what a code is evidence
of: ``artefact`` (a corrupted record: sensor, wiring, seating), ``soil`` (the soil's own
behaviour beyond the model: bearing failure), ``stop`` (how the test was ended: a load
cap) or ``phase`` (a phase of the record that is not virgin loading: a hold, an
unload–reload, a step, the release; :mod:`.phases`); discovery never names a cause that
lines up with artefacts.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["ARTEFACT_CODES", "CODES", "MODES", "PHASE_CODES", "STOP_CODES", "QualityCode"]

#: ``off``: no screening; ``flag``: screen and report, exclude nothing; ``clean`` (default):
#: also leave spikes and pre-contact samples out of every fit (and re-zero the sinkage at the
#: contact point found).
MODES = ("off", "flag", "clean")


@dataclass(frozen=True)
class QualityCode:
    """One screening rule's code and its documentation."""

    code: str
    what: str
    why: str
    action: str
    excluded: bool = False
    nature: str = "artefact"  # "artefact" | "soil" | "stop" | "phase" (module docstring)


CODES: dict[str, QualityCode] = {
    c.code: c
    for c in (
        QualityCode(
            "spike",
            "One or two samples that jump away from both neighbours by more than 10 robust "
            "noise widths and 5 % of the test's span (running median of 5), then come back. "
            "On a sparse, steep record one spike drags its neighbours' running median along; "
            "off samples within 2 of each other are read as one spike when one of them "
            "departs 3x more than the others and, set to its running median, leaves none of "
            "them off.",
            "A sensor glitch is not soil. One spiked sinkage in 2,000 samples can move a test's "
            "n from 1.2 to 0.06, and it also sets the test's range, so the equal-sinkage "
            "thinning of Section 2.1 throws away most good samples.",
            "Nothing by default: the samples are excluded from every fit and listed. Use "
            "--quality flag to keep them, and check the rig's wiring if spikes are frequent.",
            excluded=True,
        ),
        QualityCode(
            "burst",
            "A run of 1-5 samples, alone or in a cluster (candidates at most 3 samples apart), "
            "that departs from the running median of 11 samples by more than 10 robust noise "
            "widths and 5 % of the span while the 3 good samples on each side lie on one "
            "straight line (within 20 % of the burst's departure from it), every run on one "
            "side of the line. Runs after the spike rule, on the samples it kept: the median "
            "of five that the spike rule compares with is dragged along by a run of three.",
            "A burst is the sensor's or the wiring's, not the soil's. Three- and four-sample "
            "bursts in z that stay in a fit move it far (a soil's pooled Bernstein n 0.51 "
            "where the same records without them give 0.75-1.4).",
            "Nothing by default: the samples are excluded from every fit and listed. Use "
            "--quality flag to keep them; check the displacement sensor's cable and "
            "connector if bursts recur.",
            excluded=True,
        ),
        QualityCode(
            "glitch-cluster",
            "A dense run of 5 or more samples (at most a quarter of the record; candidates at "
            "most 3 samples apart) whose z or force lies beyond the record's own robust range "
            "(its 5 % to 70 % quantiles) by more than that range's width, and departs by as "
            "much (and 10 noise widths) from the 3 samples on each side: the channel went "
            "somewhere the plate cannot be and came back. Runs first, on the raw records; a "
            "run-away at the record's end (nothing after it) is never one.",
            "A portable rig's z can jump to 2-12x the record's depth for up to ~50 samples. "
            "Kept, such clusters moved a soil's pooled n from 1.38 +/- 0.06 to 0.52 +/- 0.23, "
            "made the good samples behind them look non-monotone and hid a real drift.",
            "Nothing by default: the samples are excluded from every fit and listed. Use "
            "--quality flag to keep them; check the displacement sensor's cable, connector "
            "and logger if clusters recur.",
            excluded=True,
        ),
        QualityCode(
            "pre-contact",
            "The force stays at its noise floor while the sinkage grows: the plate was zeroed "
            "above the surface (seating offset). Either a power law measured from a contact "
            "point fits the loaded part far better (residuals halved) than one measured from "
            "z = 0, or, for a near-linear curve that no shift fits much better, the early law "
            "from z = 0 (up to 35 % of the peak) puts at least 3x the floor's threshold at "
            "the end of the free travel, where the force was still at the floor (only where "
            "the force then never falls back by more than 10 % of its peak: a glitch is no "
            "rise). The contact is never placed past a sample held 5 noise widths off the "
            "floor. A record that starts under load (its first samples above 5 % of its peak "
            "force and 5 noise widths) or climbing (its first four samples rising by more "
            "than 5 noise widths) is not searched. One rule per soil and preparation: where most "
            "of its tests show a toe (median residual ratio at most 0.8), their median "
            "contact decides whether it is material (2 % of the median travel) and every "
            "test is treated alike: re-zeroed at its own contact, or at the median where its "
            "own record cannot place it; elsewhere a test needs the evidence above on its own "
            "(a shifted law on 20 loaded samples at least). The message gives the record's "
            "log-log n from z = 0 and from the contact. A contact that would leave out more "
            "than half of the record is not applied: the flag asks the question instead.",
            "Bekker's and Bernstein's z is the sinkage below the surface. An offset zero bends "
            "the curve and biases n and k; the free travel adds samples with p ~ 0.",
            "Nothing by default: samples before the contact are excluded and z is re-zeroed "
            "at the contact found (both listed). Zero the displacement at first contact in "
            "future tests.",
            excluded=True,
        ),
        QualityCode(
            "late-zero",
            "The force leaves its noise floor and is held above it while the sinkage is still "
            "z <= 0, in a loading branch continuous with the loaded record: the displacement "
            "was zeroed after the plate touched the soil. The floor and threshold are "
            "pre-contact's (the median of the first 3 forces; 5 noise widths or 1 % of the "
            "peak above it, three samples held); the branch must start at least 2 % of the "
            "test's travel before z = 0. A record that starts under load (its first samples "
            "above 5 % of its peak force and 5 noise widths, a seating preload) has no floor "
            "to leave and is not judged.",
            "Bekker's and Bernstein's z is the sinkage below the surface. Zeroed late, every "
            "sinkage is short by the travel before the zero and the loaded samples at "
            "z <= 0 are left out of fits as out of contact: n and k are biased (a simulated "
            "campaign zeroed 1.5 mm after contact fitted n = 0.70 for 0.80 and 0.99 for 1.10, "
            "kphi 28-30 % low).",
            "Nothing is excluded or corrected (the contact lies somewhere before the branch, "
            "where the force was still within the threshold, and cannot be placed reliably). "
            "Re-zero the displacement at first contact: shift that test's z before importing "
            "it. Until then compare its fit with fits of tests that are not flagged (a fit of "
            "flagged tests carries the flag).",
        ),
        QualityCode(
            "units",
            "A value whose size only makes sense in another unit (sinkage spanning more than "
            "1 m, a tool larger than 1 m, a peak pressure below 200 Pa, a shear stress above "
            "5 MPa or below 20 Pa, more than two ring revolutions), or a peak plate pressure "
            "above 100 MPa (beyond any soil, rock crushes near it: a force in mN read as N or "
            "the wrong column; fix the force column), or one test off the other "
            "tests of its soil by a unit's factor (peak pressure below 1/100 of their median: "
            "kN among N; sinkage span above 30x their median: cm or mm among m), or no "
            "positive force in contact (a reversed load cell), or a sinkage that falls "
            "through the record (a reversed displacement).",
            "A number in mm read as m fits without complaint and moves kφ by orders of magnitude.",
            "Fix the column or import it with its unit (docs/importing.md). Fits of these "
            "tests are not to be used.",
        ),
        QualityCode(
            "load-capped",
            "Three or more sinkage tests of one soil end at nearly the same force (spread "
            "max/min - 1 below 10 %) while their maximum sinkage differs by more than 25 % "
            "and five times the force's spread: the tests were stopped at a load, not at a "
            "depth.",
            "The depth reached is then an outcome of the soil's stiffness: soft tests run "
            "deeper, and a pooled fit leans toward their shape (pooled n can lie outside "
            "every test's n). z_max must never be read as a cause.",
            "Fit within a common sinkage window (z_max) that every test reached, and compare "
            "per-test exponents with the pooled one (aggregation-bias flag of the fit).",
            nature="stop",
        ),
        QualityCode(
            "bearing-failure",
            "The record ends more than twice as deep as the test's own early power law puts "
            "it at the same force (and at least 25 % of its final sinkage beyond it): "
            "F = k z^n fitted in log-log space to the samples up to where the force first "
            "reaches 35 % of its peak (and above 5 % of it). The onset is the last sample "
            "within 1.25x of that law. The run-on must also be long (at least 0.5 plate sizes "
            "b beyond the law: punch-through) or end on a force plateau (less than 10 % force "
            "gained over the last 25 % of the sinkage): a shorter run-on whose force keeps "
            "rising is the bend of a record stopped early. A force that gains less than 2 % "
            "over the last 25 % of the sinkage is flagged whatever the law says (a plateau: "
            "the soil failed or the rig reached a force limit; onset where the force first "
            "comes within 2 % of its end). Where a seating offset was found, the rule runs on "
            "the loaded record with z from the contact. Noise is allowed for: the excess must "
            "hold once 2.5 standard errors of the early law's log-force at the record's end "
            "are taken off, and a plateau must be flat beyond the noise (a line through the "
            "tail gains under 2 %, and under 10 % with two standard errors).",
            "The soil under the plate failed (punch-through), or the rig stopped loading (a "
            "force limit); pressure–sinkage models describe the loading before. Samples past "
            "the onset drag n toward 0.",
            "Fit within the proposed window (listed, with the --z-max item that sets it): "
            "z_max = the failed test's onset for that test only, or, where more than half "
            "of a plate's tests (soil and plate size b) failed, the smallest onset for all "
            "of the plate's tests; e.g. soilstats identify --z-max test_id=<test>:<onset>.",
            nature="soil",
        ),
        QualityCode(
            "release",
            "The force collapses (loses more than 50 % of its running maximum) while z stands "
            "still or backs off by less than 10 % of the travel, and the record ends without "
            "loading again: the drive let go or the test was stopped, and z no longer tracks "
            "the plate. A hold at the peak just before (z standing, force within 5 % and 10 "
            "noise widths of its maximum) belongs to it. Found from z and force alone, "
            "whatever the sampling clock.",
            "The release is no soil response. Read as loading it looks like bearing failure "
            "(sinkage at a falling force) and the hold before it like a clipped channel.",
            "Nothing: its samples are left out of every fit (listed). Cut records at the force "
            "peak when exporting, if you like.",
            excluded=True,
            nature="phase",
        ),
        QualityCode(
            "hold",
            "The drive stands still (z advances by at most 4 z-noise widths, or a quarter of "
            "what loading would cover in the time) while the force relaxes below its running "
            "maximum by more than 5 % (and 10 force-noise widths) but less than 50 %; the "
            "reload after it, until the force is back within 1 % (and 3 noise widths) of its "
            "running maximum, belongs to it.",
            "A hold measures stress relaxation, and the reload after it an elastic branch "
            "stiffer than virgin loading: neither is the pressure-sinkage law of a plate "
            "pushed into virgin soil.",
            "Nothing: the hold and its reload are left out of every fit (listed) and kept "
            "as data for an elastic model. Avoid pauses while loading where the protocol "
            "allows.",
            excluded=True,
            nature="phase",
        ),
        QualityCode(
            "unload-reload",
            "The force falls by more than 50 % of its running maximum at standing z, or falls "
            "while z backs off by more than 2 % of the travel, and loading resumes: the "
            "samples from the fall until the force regains its running maximum (the unload "
            "and the reload below the virgin curve).",
            "Unloading and reloading follow the soil's elastic law, not Bekker's or "
            "Bernstein's: fitted as loading they drag n down.",
            "Nothing: the branch is left out of every fit (listed) and kept as data for an "
            "elastic (unload-reload) model.",
            excluded=True,
            nature="phase",
        ),
        QualityCode(
            "step",
            "The force drops below its running maximum by more than 5 % (and 10 robust noise "
            "widths of the record's force) while z keeps advancing, until it is back within "
            "1 % of that maximum: a sudden local collapse of a dense soil, or a jolt of the "
            "rig.",
            "The samples of the drop and its recovery lie below the loading curve; they are "
            "no point of the pressure-sinkage law.",
            "Nothing: the samples are left out of every fit (listed). Repeated steps in one "
            "soil are worth a look: a layered bed, or a rig that sticks and slips.",
            excluded=True,
            nature="phase",
        ),
        QualityCode(
            "duplicate",
            "A test whose samples are identical, value for value and in order, to an earlier "
            "test's (sinkage: z and force, shear: angle, torque and normal force), with at "
            "least 5 distinct force (torque) values. Independent tests never repeat a record "
            "to the last digit; a flat, dead channel over a commanded z grid can, and is "
            "left to the other rules.",
            "Two tests are two preparations; a copied record counts one preparation twice. "
            "The pooled fit weighs it double and the test-level σ shrinks (by √2 when every "
            "test is doubled), so the campaign looks better replicated than it is.",
            "Nothing by default: the later copy is left out of every fit and listed (with "
            "--quality flag it is kept and a fit of it carries the flag). Find out "
            "which test the copy should have been (an export or file-naming slip).",
            excluded=True,
        ),
        QualityCode(
            "zero-drift",
            "The start force (median of the samples at or above the surface, z <= 0, among "
            "the first 3; a record with none is not judged) of the sinkage tests of a series "
            "(one soil and setup: every log column but test_id, operator, the order columns "
            "and any column with a value of its own for every test) trends with test order (a "
            "sequence column, else a date/time column such as `start_time` — ISO dates or "
            "clock times, as discovery reads them — else repetition, else the log's row "
            "order): a Kendall test "
            "stratified by series, exact permutation p-value below 0.01 after Bonferroni over "
            "the soils; in a series whose own trend has that sign (one-sided p at most 0.1, so "
            "at least 4 tests) and a Theil-Sen drift of at least 1 % of its median peak force "
            "across it, its slope at least 3 standard errors (from the start forces' robust "
            "scatter around the trend). Flagged: the tests whose drift since the series' "
            "first test reaches that 1 %.",
            "A load cell whose zero drifts over a test day adds a constant force to each "
            "record that grows with test order. It fits silently (the offset bends n and k) "
            "and makes test order (repetition) look like a cause of the soil's behaviour.",
            "Re-zero the load cell before every test. Nothing is excluded or corrected (the "
            "offset is estimated from 3 samples; only the rig's zero log can confirm it): "
            "compare the fit with one of the unflagged tests (a fit of flagged tests carries "
            "the flag). Discovery reports causes that follow test order as a residue of the "
            "data, not a cause.",
        ),
        QualityCode(
            "starts-loaded",
            "The loading record's first samples (median of 3) already carry more than 5 % of "
            "its peak force and 5 force-noise widths, at a first z beyond 2 % of the travel: "
            "the logger started after the plate was loaded, and the record's first "
            "millimetres are missing. Flag only.",
            "Without its toe a record cannot show a seating offset or a late zero, and its "
            "early law (bearing failure, the contact rules) starts mid-curve; the fit covers "
            "only the sinkage recorded.",
            "Nothing is excluded. Check that z was zeroed at the surface (not where logging "
            "began); if it was, the fit holds for the range recorded. Start logging before "
            "contact in future tests.",
        ),
        QualityCode(
            "gap",
            "A step in z of more than 20 times the record's median step and 5 % of its "
            "travel: a stretch of sinkage with no samples (the logger paused or dropped "
            "data). Flag only; rows: the first sample after each gap.",
            "A fit has no information inside the gap; a gap where the curve bends (toe, "
            "failure onset) hides where it bends, and a thinning by equal sinkage weighs the "
            "samples around it differently.",
            "Nothing is excluded. Check the logger's buffer and sampling settings; when a "
            "gap falls where a window or onset is decided, read that decision with care.",
        ),
        QualityCode(
            "non-monotone",
            "The sinkage falls back below its running maximum by more than 2 % of the test's "
            "travel over three or more samples of the loading record from its contact on (a "
            "slipping mount, a z glitch longer than a burst): the approach and the phases "
            "that are not loading are not judged.",
            "Pressure–sinkage models describe monotone loading: a sinkage that falls back "
            "while the force keeps to its curve is a mount or sensor fault, not soil.",
            "Check the displacement mount and its cable; fit within a window that ends "
            "before the fallback.",
        ),
        QualityCode(
            "saturation",
            "Four or more samples of the loading record (from its contact on) sit exactly at "
            "a channel's maximum while the other channel keeps changing: the sensor or its "
            "amplifier clipped. z standing at its maximum in a hold or a release is no "
            "clipping.",
            "Clipped values are not the soil's response; they flatten the top of the curve.",
            "Re-run with a larger sensor range, or fit within a window below the clipping.",
        ),
    )
}

#: Codes of a corrupted record (sensor or seating artefacts).
ARTEFACT_CODES = tuple(c for c, q in CODES.items() if q.nature == "artefact")
#: Codes that describe how a test was ended, not a fault of its record.
STOP_CODES = frozenset(c for c, q in CODES.items() if q.nature == "stop")
#: Codes of a record's phases that are not virgin loading (left out of fits, no fault).
PHASE_CODES = frozenset(c for c, q in CODES.items() if q.nature == "phase")
