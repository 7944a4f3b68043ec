from sim_hil.cli import main

raise SystemExit(main())
