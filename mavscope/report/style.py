"""The report page's style sheet and the colours of its drawings (inline in the page: nothing is loaded)."""

CSS = """
:root{--fg:#1b1f24;--muted:#57606a;--line:#d0d7de;--bg:#fff;--band:#f6f8fa;--error:#b42318;--warn:#b54708;
--note:#175cd3;--chat:#667085;--ok:#067647}
*{box-sizing:border-box}
body{font:14px/1.45 system-ui,-apple-system,"Segoe UI",Roboto,"DejaVu Sans",sans-serif;color:var(--fg);
background:var(--bg);margin:0 auto;max-width:1200px;padding:16px}
h1,h2,h3{overflow-wrap:anywhere}
h1{font-size:24px;margin:0 0 4px}h2{font-size:20px;margin:28px 0 8px;border-bottom:2px solid var(--line);
padding-bottom:4px}h3{font-size:16px;margin:20px 0 6px}
code,.mono{font-family:ui-monospace,"DejaVu Sans Mono",Menlo,Consolas,monospace;font-size:12.5px;
overflow-wrap:anywhere}
.muted{color:var(--muted)}
table{border-collapse:collapse;width:100%;margin:6px 0 10px}
th,td{border-bottom:1px solid var(--line);padding:4px 6px;text-align:left;vertical-align:top;
overflow-wrap:break-word}
th{background:var(--band);font-weight:600}
td.num,th.num{text-align:right;white-space:nowrap}
.scroll{overflow-x:auto}
.kv th{width:14em}
.sha256,code.hash{word-break:break-all}
figure{margin:0 0 8px}
figure.plot svg{min-width:560px}
.nowrap{white-space:nowrap}
.sev{display:inline-block;border-radius:3px;padding:0 6px;color:#fff;font-size:12px;font-weight:600}
.sev-error{background:var(--error)}.sev-warn{background:var(--warn)}.sev-note{background:var(--note)}
.sev-chat{background:var(--chat)}
.counts span{margin-right:12px}
.cards{display:grid;grid-template-columns:repeat(auto-fit,minmax(170px,1fr));gap:10px;margin:8px 0}
.card{border:1px solid var(--line);border-radius:6px;padding:8px 10px;background:var(--band)}
.card b{display:block;font-size:20px}
details{margin:6px 0}summary{cursor:pointer;font-weight:600}
svg{width:100%;height:auto;background:#fff;border:1px solid var(--line);border-radius:4px}
svg text{font:11px system-ui,sans-serif;fill:#344054}
.track0{stroke:#175cd3}.track1{stroke:#c11574}.track2{stroke:#067647}.track3{stroke:#b54708}
.more{color:var(--muted);font-style:italic}
nav ul{columns:3 200px;padding-left:18px;margin:4px 0}
nav a{overflow-wrap:anywhere}
.legend span{margin-right:14px;white-space:nowrap}
.sw{display:inline-block;width:12px;height:3px;vertical-align:middle;margin-right:4px}
@media (max-width:640px){body{padding:8px;font-size:13px}.kv th,.kv td{display:block;width:auto}
.kv th{border-bottom:0;padding-bottom:0}
table.wide thead{display:none}table.wide tr{display:block;border-bottom:2px solid var(--line);padding:4px 0}
table.wide td{display:block;border:0;padding:1px 4px}table.wide td::before{content:attr(data-label) ": ";
font-weight:600;color:var(--muted)}td.num{text-align:left}}
@media print{body{max-width:none;font-size:11px}nav{display:none}h2{break-after:avoid}
table,svg{break-inside:auto}tr{break-inside:avoid}}
"""

VERDICT_COLOURS = {"valid": "#067647", "unsigned": "#667085", "invalid": "#b42318", "replay": "#c11574",
                   "no-key": "#175cd3"}
