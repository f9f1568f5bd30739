"""Calibration, the feature in one place: parameter values from a lab's measurements (docs/calibrate.md).

Built on the shared stages (scenes and studies' cases from `inputs` and `plans`, simulations through
`execution.jobs`, the maths in `fitting`, which knows no scene), in the order its modules import one another:

- `measurements`: PEtab's measurement table read and checked (CSV or TSV, one line per problem);
- `table`: the calibration file's [data] (the table, the unit of its times) and what a row's numbers must be;
- `methods`: every fitting method declared once — its [method] keys and rules, its maths, the memory it holds,
  its part of calibration.nc, its pictures and warnings (`Method`); `method_spec`: the [method] table made from
  those declarations;
- `noise`: σs the table names to estimate; `spec`: the calibration file's schema; `problem`: the file read
  into a `CalibrationPlan` (parameters with their names, bounds and scales, the measurements in T*);
- `cost`: what a calibration needs before it runs (`show` says it, `calibrate` refuses what cannot fit);
- `evaluator`: the simulations as the fit sees them (points of the unit cube -> weighted residuals);
- `report` (with `report_noise`, `report_posterior`, `units`, `petab`): calibration.nc, calibration.md and
  PEtab's simulation.tsv; `pictures`: the figures;
- `twin`: a twin experiment's measurement table (the model at known parameters, plus noise).

The command `biostudy calibrate` (`commands.calibrate`) runs a plan with its method and writes what it found.
"""
