from hfsmc.cli import main

main()
