"""The event-driven engine: hard spheres and disks moved collision by collision (Pérez
Sec. 2).  collision.py holds the collision rule, flight.py free flight and event times,
calendar.py the event calendar, events.py the compiled event loop, engine.py the
EventDriven engine, settings.py its ``[engine]`` settings and registry entry."""
