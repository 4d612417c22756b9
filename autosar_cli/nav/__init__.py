"""Navigation: SAR-MIN (UKF + RTS smoother), its baselines, and what the drive's own sensors get wrong."""
