"""Simulation: motion sources (procedural gait, mapped mocap) and simulated sensors."""
