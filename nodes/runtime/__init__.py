"""What every node of the project runs on: start-up and --help, parameters, executors, sim time."""
