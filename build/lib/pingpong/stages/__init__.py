"""One entry per workflow rule: `pingpong.stages.<rule>.main(ctx)` reads the rule's inputs, calls the
stage group's functions and writes its outputs (docs/architecture.md, "Where each rule's code lives")."""
