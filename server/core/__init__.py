"""The service's base: settings, the one error shape, who may do what, start-up checks, and the disk and
SQLite helpers every other package uses. Imports nothing else of server/."""
