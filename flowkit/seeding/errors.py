"""``SeedError``, on its own: the seed specs (integrate/seeds.py) hand their data-drawn forms to
``seeding.data``, which raises it too, so neither module can hold it for the other."""


class SeedError(ValueError):
    """Seeds that cannot be made: bad file, bad spec, bad arguments."""
