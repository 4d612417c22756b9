"""The simulator: synthetic drive logs of a car with full dynamics, its sensors and radar, and their truth."""
