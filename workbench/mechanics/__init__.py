"""The mechanics layer: what a model's elements do, symbolically (book ch. 4, 9, 10.2, 11.1).

``joints`` (one dispatch over every joint type), ``kinematics`` (the spanning tree in joint
coordinates), ``forces`` (force elements and energies), ``newton_euler`` (M and h of the
bodies projected onto any generalized velocities), ``lagrangian`` (L in joint coordinates
for energy-based formalisms), ``topology`` (tree, loops, degrees of freedom, assembly).
Generic over NumPy and CasADi; no formalism and no integrator appear here.
"""
