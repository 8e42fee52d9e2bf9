"""Cross-validation of the backends: Table-I comparisons and the speed-against-error sweep."""
