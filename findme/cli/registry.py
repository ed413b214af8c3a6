"""The commands of ``findme``, the module of each, and how ``findme --help`` groups them.

Each module named here is a module of this package with ``register(sub)`` adding its
commands; the parser (``findme.cli.build_parser``) imports them by name when it is built:
all of them for ``findme --help``, only the one a command line names otherwise (a command
then starts without loading the others' dependencies). ``GROUPS`` lists every command once,
under a title.
"""

#: command -> the module that registers it, in the order the parser registers them
COMMANDS = {
    "demo": "demo",
    "hypotheses": "single", "locate": "single",
    "eval": "evaluate",
    "motion": "motion",
    "plan": "plan", "locate-in": "plan",
    "run": "run",
    "serve": "serve", "router": "serve",
    "status": "status",
    "app": "app",
    "up": "up",
    "send": "send",
    "recover": "record", "view": "record", "replay": "record", "regress": "record",
    "export": "export",
}

COMMAND_MODULES = tuple(dict.fromkeys(COMMANDS.values()))

GROUPS = (
    ("Try it", ("demo", "run")),
    ("Photos on this machine", ("hypotheses", "locate", "motion", "plan", "locate-in")),
    ("Services (one process, or many on one or more machines)",
     ("up", "send", "status", "app", "serve", "router")),
    ("Recorded sessions (MCAP)", ("export", "view", "replay", "regress", "recover")),
    ("Evaluation", ("eval",)),
)
