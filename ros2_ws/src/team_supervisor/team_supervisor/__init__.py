"""Team supervisor: the team's safety state and the operator's command line."""
