"""Test code of other projects, vendored verbatim (each folder's README says from where and under which licence)."""
