from export.train.trainer import main

main()
