"""The fleet in order: the ranking read from the forecast cache's rows, its pages, its kept
answers and the export."""
