"""The study on top of the plugin: the launcher and its results store, the report, the forensics and the command line.
The plugin never imports it."""
