"""busarm: drive LX bus-servo robotic arms, real or simulated."""

__version__ = "0.1.0"
