"""Fitting a model to measurements: pure maths on the unit cube of the bounds, simulations asked for in rounds.

`objective` (the weighted residuals at a batch of points, each point once), `rounds` (fits as generators that
yield the points they need; one loop evaluates every fit's request at once), `least_squares`
(Levenberg-Marquardt with finite-difference Jacobians against the observables' resolution),
`uncertainty` (covariance, standard errors, correlations, the fitted model's band), `profiles`
(profile likelihoods, 95 % intervals, identifiability), `estimate` (multi-start, then profiles),
`surrogate` (Gaussian processes of the residuals), `sampling` (emcee and its diagnostics), `posterior`
(the posterior on the surrogate, its error measured on held-out runs).
Nothing here knows what a scene or a simulation is: `calibration.evaluator` hands it the residuals, and the
methods a calibration offers are declared in `calibration.methods`.
"""
