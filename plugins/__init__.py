"""Built-in plugins: formalisms and integrators, discovered by the workbench registry."""
