"""The application layer: what the commands run, built on the library packages.

:mod:`~ikfusion.app.pipeline` solves a recording (calibrate, bridge lost samples, solve every
frame), :mod:`~ikfusion.app.session` solves one actor or a session of actors into result folders,
:mod:`~ikfusion.app.uwb_aiding` tracks the UWB tags and turns them into the
:mod:`~ikfusion.app.correction` of the body's drift, :mod:`~ikfusion.app.evaluate` (plots in
:mod:`~ikfusion.app.evaluate_plot`) scores a result against a simulated truth, and
:mod:`~ikfusion.app.demo` runs simulate, solve and evaluate end to end.
"""
