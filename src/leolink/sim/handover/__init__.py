"""Handover: policies, 3GPP triggers, the layer-3 filter, the controller's step, RLF and KPIs."""
