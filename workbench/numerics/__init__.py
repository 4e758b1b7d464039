"""The numerics layer: ``backend`` (NumPy or CasADi), ``rotations``, ``geometry`` (pose
errors), ``linalg`` (independent constraint rows and columns, Gauss-Newton)."""
