from drkfs_lab.record_tables import main

main()
