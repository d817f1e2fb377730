"""One module per ``gcs-voice`` sub-command; each has ``add_arguments(parser)`` and ``run(args) -> int``.

Modules import heavy libraries (models, pymavlink) inside ``run`` only, so ``--help`` stays instant.
"""
