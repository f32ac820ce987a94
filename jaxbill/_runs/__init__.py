"""Long runs in bounded memory that survive faults: ``jb.run``, its files and its guards."""
