"""Private foundations shared by every layer: array types, argument checks, the float64 policy,
the damped Newton solver with implicit derivatives, atomic files, the package version."""
