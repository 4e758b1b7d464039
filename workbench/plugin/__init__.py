"""The plugin layer: the three contracts, their registry and their typed options.

``problem``, ``formalism`` and ``integrator`` write each contract down as a numbered list;
``registry`` finds plugins (built-in packages, then entry points) and keeps a broken one
from stopping the others; ``options`` types a plugin's options; ``scaffold`` writes a new
plugin from ``templates/``. A plugin imports from here and from ``workbench.model`` and
``workbench.equations``; nothing here knows a particular plugin.
"""
