"""rh_dataset: the Relighting Humans generator (scene spec -> character -> pose -> light -> Mitsuba -> dataset)."""
__version__ = "0.1.0"
