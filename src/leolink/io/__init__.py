"""Files in and out: the one atomic writer, readers (tracks, TLEs), tables, sinks, plots."""
