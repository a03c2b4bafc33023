"""dong2018 on a three-axis turntable: plans, simulation, the exact / linear /
multi-position calibrations, frame unification, consistency checks, plan design, the
table's own errors from the data, and the batched Monte Carlo."""
