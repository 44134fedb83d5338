# calibration.png from calibration.csv (written by fillgs); re-plot with: gnuplot calibration.gp
set terminal pngcairo size 960,600 noenhanced font 'DejaVu Sans,10'
set datafile separator ','
set border 3 lc rgb '#404040'
set tics nomirror
set grid ytics lc rgb '#dddddd' lt 1
set style fill solid 0.85 noborder
set output 'calibration.png'
set title 'refiner calibration: random.w-none (random views)'
set xlabel 'parallax angle to the reference view (degrees, median over the view)'
set ylabel 'PSNR against the truth (dB)'
set lmargin at screen 0.09
set rmargin at screen 0.74
set bmargin at screen 0.12
set tmargin at screen 0.9
set key outside right top vertical Left reverse noautotitle
set grid xtics ytics lc rgb '#dddddd' lt 1
set xrange [-6.5:161.5]
set yrange [5.90876554:23.9818711]
plot 'calibration.csv' skip 1 using 2:($1 == 0 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#3c78b4' title 'where the reference saw, n3v_s1', \
     'calibration.csv' skip 1 using 2:($1 == 1 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#d62728' title 'where the reference saw, n3v_s2', \
     'calibration.csv' skip 1 using 2:($1 == 2 ? $3 : NaN) with points pt 7 ps 1.1 lw 1.5 lc rgb '#2ca02c' title 'where the reference saw, n3v_s3', \
     'calibration.csv' skip 1 using 2:($1 == 3 ? $3 : NaN) with linespoints pt 7 ps 1.1 lw 1.5 lc rgb '#9467bd' title 'where the reference saw, mean per 5 degrees', \
     'calibration.csv' skip 1 using 2:($1 == 4 ? $3 : NaN) with linespoints pt 7 ps 1.1 lw 1.5 lc rgb '#ff7f0e' title 'whole image, mean per 5 degrees', \
     'calibration.csv' skip 1 using 2:($1 == 5 ? $3 : NaN) with linespoints pt 7 ps 1.1 lw 1.5 lc rgb '#7f7f7f' title 'the render it was given, mean per 5 degrees'
