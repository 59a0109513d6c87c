"""One module per `posecam` sub-command."""
