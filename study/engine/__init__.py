"""The session engine: protocols, counterbalancing, sessions and the trial loop."""
