from mavscope.cli import main

raise SystemExit(main())
