"""grip fleet: many drive logs through grip's own code, as Ray tasks.

Every per-log figure comes from the ``grip`` binary (``grip inspect --json``,
``grip replay --json``); this package only schedules those calls on Ray
(in-process locally, or a cluster through ``RAY_ADDRESS``), collects the JSON
objects into tables, and adds up the counts they carry.
"""

__version__ = "0.1.0"
