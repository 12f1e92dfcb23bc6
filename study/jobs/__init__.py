"""Long jobs as plain functions: synthetic studies, demonstrations, scene drawings."""
