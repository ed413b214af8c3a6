"""The command modules of ``findme``, in the order the top-level parser registers them.

Each is a module of this package with ``register(sub)`` adding its sub-commands; the parser
(``findme.cli.build_parser``) imports them by name when it is built.
"""

COMMAND_MODULES = ("demo", "single", "evaluate", "motion", "plan", "run", "serve", "status",
                   "app", "up", "send", "record", "export")
