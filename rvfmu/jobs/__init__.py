"""One module per job of `rvte`: its report (what it prints, its JSON) and its function.
`rvfmu.api` is their public face and re-exports every one."""
