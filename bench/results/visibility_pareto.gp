# visibility_pareto.png from visibility_pareto.csv (written by fillgs); re-plot with: gnuplot visibility_pareto.gp
set terminal pngcairo size 960,600 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'visibility_pareto.png'
set title 'visibility: time against visible-set recall (vs exact)'
set xlabel 'time (s, log scale)'
set ylabel 'recall'
set lmargin at screen 0.09
set rmargin at screen 0.74
set bmargin at screen 0.12
set tmargin at screen 0.9
set key outside right top vertical Left reverse noautotitle
set grid xtics ytics lc rgb '#dddddd' lt 1
set logscale x 10
set format x '%g'
set xrange [0.179507657:103.965728]
set yrange [0.263069154:1.05458747]
set label "frustum" at 0.273848971, 1 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4 plain 3D" at 1.33956888, 0.611034748 left font ',9' tc rgb '#3c78b4'
set label "raytraced s8" at 1.95701939, 0.317656624 left font ',9' tc rgb '#3c78b4'
set label "raytraced s4" at 7.54824789, 0.657126902 left font ',9' tc rgb '#3c78b4'
set label "exact" at 9.34470886, 1 left font ',9' tc rgb '#3c78b4'
set label "raytraced s2" at 23.1514022, 0.902506892 left font ',9' tc rgb '#3c78b4'
set label "raytraced s1" at 30.3947147, 0.995741469 left font ',9' tc rgb '#3c78b4'
plot 'visibility_pareto.csv' skip 1 using 2:($1 == 0 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#3c78b4' title 'synthetic 320x240'
