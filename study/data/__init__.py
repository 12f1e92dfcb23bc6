"""The study's data: the database schema and storage, rerun recordings, checks and exports."""
