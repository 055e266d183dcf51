"""The predictor: from a sweep's measurements to mu*, its interval and the transition's type.

The public doors are :mod:`service.analysis.predict` (``predict``, ``Prediction``,
``paper_rule``) and :mod:`service.analysis.classify` (``classify``, ``Classification``); this
package is the engine behind them. docs/predictor.md is the longer map with, for each piece,
the failure it fixes, the test that pins it and the calibration it rests on (the ledger).

Pipeline, top to bottom (each module imports only from the ones below it)::

    prediction       predict(): sweep -> fits -> interval -> imperfect laws -> type rules ->
                     alarm -> Prediction (one mu*, inside its interval, that every flag refers to)
    imperfect        decide(): what the imperfect pitchforks change in the answer: a softening
                     one snaps at a fold before mu*, a stiffening one never loses stability
    cusp             assess(): the unfolded (imperfect) pitchforks fitted against the perfect
                     one on a window of nearest points (CuspWindow, Imperfection)
    interval         fit_sweep(): the law given or the classified candidates refitted on their
                     own windows; interval(): profile or mixture interval, fewer-terms rivals,
                     truncation spread
    classification   classify_sweep(): candidates compared, the type named or withheld
    rules            the withholding rules as a table (code, reason, pinning test, check)
    compare          the candidates' fits on a common window, BIC weights, rivals, free exponents
    damping          the damping of rate (omega) data, kept only on decisive evidence
    windows          informative window and number of corrections (chi-square), noise estimate
    exponents        free exponents a and b (profile over the exponent)
    likelihood       the profile likelihood over mu* (variable projection)
    cache            FitCache: every fit of one call memoised by its exact inputs
    laws             the laws as values in one table (exponents, corrections, what they predict)
    paper_rule       the paper's two-point rule (the baseline every result carries)
    sweep            Sweep: validation at the door, repeated controls averaged, rows past the
                     transition dropped
    _kernels.laws    compiled law residuals (numba)
    _kernels.fold    compiled secondary-fold (conformal) parameter profile
    _kernels.profile compiled searches over mu*
    _kernels.brent   Brent's bookkeeping shared by the three searches
    _kernels.cusp    compiled cusp law: amplitude, stiffness, misfit, profile over G
    _dist            normal and chi-square quantiles from scipy.special (scipy.stats' values,
                     without importing scipy.stats)

Adding a law: a row of :data:`laws.LAWS` (and, for a new family, the module that fits it).
Adding a reason to withhold a type: a row of :data:`rules.RULES`.
"""
