// subgroup_sums() where the device has no subgroups: SUBGROUP_SUMS is then left off; this only
// keeps the shader whole.
fn subgroup_sums() {}
