# The `shapes` preset with a gradient ramp: a 2D transfer function (docs/benchmarks.md,
# "Fifteenth step").
gradient 0.02 0.3
point 0.0 0.35 0.55 1.0 0.0
point 0.08 0.35 0.55 1.0 0.0
point 0.12 0.35 0.55 1.0 0.06
point 0.31 0.35 0.55 1.0 0.06
point 0.36 1.0 0.55 0.2 0.0
point 0.40 1.0 0.55 0.2 0.0
point 0.55 1.0 0.6 0.25 0.7
point 0.8 1.0 0.8 0.45 0.95
point 1.0 1.0 1.0 0.9 1.0
