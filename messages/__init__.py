"""The inter-process contract: LCM types (generated at build time into build/gen/python, package `t1`)
and messages/contract.json (joint order, channel names, default LCM URL)."""
