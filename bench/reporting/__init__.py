"""Layer 6: tables, figures, renders, reports, the paper's reproduction, the dashboard, margins. Imports the layers below."""
