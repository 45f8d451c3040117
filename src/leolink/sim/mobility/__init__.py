"""UT motion: the mobility models and the populations that use them."""
