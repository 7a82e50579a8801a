"""Private foundations shared by every layer: array types, argument checks, the float64 policy,
the damped Newton solver with implicit derivatives, and the old-import-path aliases."""
