"""Active localization: a task env in which a policy drives so that a localizer becomes right and sure quickly
(``pimm/ActiveLocalization-v0``), and its motion primitives."""
