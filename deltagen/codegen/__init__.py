"""Robot-independent stages of the pipeline: kernel description → CSE + C printing →
Jinja rendering."""
