"""Recording and viewing: the recorder service and the MCAP layout, writer, reader and
recovery; the Foxglove view channels; the Rerun viewer service."""
