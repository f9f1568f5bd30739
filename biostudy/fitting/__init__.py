"""Fitting a model to measurements: pure maths on the unit cube of the bounds, simulations asked for in rounds.

`rounds` (fits side by side in threads, their points evaluated together), `least_squares`
(Levenberg-Marquardt with finite-difference Jacobians against the observables' resolution),
`uncertainty` (covariance, standard errors, correlations, the fitted model's band), `profiles`
(profile likelihoods, 95 % intervals, identifiability), `estimate` (multi-start, then profiles),
`surrogate` (Gaussian processes of the residuals), `sampling` (emcee and its diagnostics), `posterior`
(the posterior on the surrogate, its error measured on held-out runs).
Nothing here knows what a scene or a simulation is: `commands.calibrate` hands it the residuals.
"""
