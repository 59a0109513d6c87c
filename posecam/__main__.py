from posecam.cli import main

main()
